"""The check of whether `resonance_input` would change a finished benchmark world
(experiments/band_input_check.py): which tries of a world's rounds it retrains."""

import pandas as pd
from conftest import experiment


def test_each_band_of_each_round_is_checked_once(tmp_path):
    bic = experiment("band_input_check")
    band, other = "resonance:rotor_rpm:center=270.7,width=3.222", "resonance:rotor_rpm:center=244.9,width=3.222"
    pd.DataFrame(dict(round=[1, 1, 1, 2, 2], operator=["resonance", "resonance", "input", "resonance", "resonance"],
                      proposal=[band, band, "input:nz_g", band, other],
                      augment=["gain", "input", "input", "gain", "gain"])).to_csv(tmp_path / "rounds.csv", index=False)
    got = bic.band_rows(tmp_path)
    assert list(zip(got["round"], got.proposal)) == [(1, band), (2, band), (2, other)]
    # a table without the proposal column: the band as tried, without its gain's fit
    pd.DataFrame(dict(round=[1], operator=["resonance"], augment=["gain"],
                      candidate=["resonance:rotor_rpm:center=270.7,gain=1.2,gain_unit=10,width=3.222"])).to_csv(
        tmp_path / "rounds.csv", index=False)
    assert list(bic.band_rows(tmp_path).proposal) == [band]
    (tmp_path / "rounds.csv").write_text("\n")  # a reference baseline's: no rounds
    assert bic.band_rows(tmp_path).empty and bic.band_rows(tmp_path / "missing").empty


def test_a_band_is_retrained_at_full_precision_where_the_table_keeps_it():
    from types import SimpleNamespace

    from pvvjax.discovery.candidates import Candidate

    bic = experiment("band_input_check")
    tried = Candidate("resonance", ("rotor_rpm",), {"center": 247.46321, "width": 3.2219, "gain_unit": 10.0,
                                                     "gain": 1.2})
    row = SimpleNamespace(candidate=tried.key, parameters=tried.parameters_json, proposal="unused")
    assert bic._proposal(row).parameters == {"center": 247.46321, "width": 3.2219}
    old = SimpleNamespace(candidate=tried.key, parameters=float("nan"), proposal=bic._without(tried).key)
    assert bic._proposal(old).parameters == {"center": 247.5, "width": 3.222}  # a table before the column
