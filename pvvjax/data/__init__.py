"""Flight-test campaigns and what is derived from them at load time.

`campaign` reads, validates and writes a campaign folder (data-contract §1), `plausibility`
holds the physical rules beyond ranges; `batch` pads
its records into arrays with a mask; `features` derives μ, MLF, C_W and C_W/σ·n; `units`
converts foreign columns; `constants` holds the aircraft's rotor constants.
"""

from .batch import BLOCK, RecordBatch, bucket_size, pad_rows, sample_widths, take_rows, to_batch, unpad_rows
from .campaign import (
    MANEUVERS,
    REQUIRED_CHANNELS,
    Campaign,
    CampaignError,
    CampaignWarning,
    Problem,
    campaign_from_frames,
    load_campaign,
    validate_campaign,
    write_campaign,
)
from .constants import DEG_TO_RAD, FPM_TO_FT_S, KT_TO_FT_S, RPM_TO_RAD_S, UH60A, Aircraft
from .features import (
    DERIVED_FEATURES,
    advance_ratio,
    blade_loading,
    derive_features,
    maneuver_load_factor,
    thrust_coefficient,
    tip_speed_ft_s,
)
from .fingerprint import campaign_files, campaign_fingerprint, frames_fingerprint, tables_fingerprint
from .plausibility import LIMITS, MIN_SAMPLES_PER_CYCLE, plausibility
from .units import CANONICAL_UNITS, KNOWN_UNITS, ColumnMap, conversion_factor

__all__ = [
    "Aircraft",
    "BLOCK",
    "CANONICAL_UNITS",
    "Campaign",
    "CampaignError",
    "CampaignWarning",
    "ColumnMap",
    "DEG_TO_RAD",
    "DERIVED_FEATURES",
    "FPM_TO_FT_S",
    "KNOWN_UNITS",
    "KT_TO_FT_S",
    "LIMITS",
    "MANEUVERS",
    "MIN_SAMPLES_PER_CYCLE",
    "Problem",
    "REQUIRED_CHANNELS",
    "RPM_TO_RAD_S",
    "RecordBatch",
    "UH60A",
    "advance_ratio",
    "blade_loading",
    "bucket_size",
    "campaign_files",
    "campaign_fingerprint",
    "campaign_from_frames",
    "conversion_factor",
    "derive_features",
    "frames_fingerprint",
    "load_campaign",
    "maneuver_load_factor",
    "pad_rows",
    "plausibility",
    "sample_widths",
    "tables_fingerprint",
    "take_rows",
    "thrust_coefficient",
    "tip_speed_ft_s",
    "to_batch",
    "unpad_rows",
    "validate_campaign",
    "write_campaign",
]
