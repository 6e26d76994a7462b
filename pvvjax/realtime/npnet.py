"""A trained network as plain NumPy, for a simulator host (imports no JAX).

`NumpyNet.load("net.npz")` reads a parameter file written by pvvjax (`.npz` read with
`allow_pickle=False`); calling it evaluates the net. At load time the input and output
scalings are folded into the first and last layers and masked (padding) units are
dropped, so one prediction is a few small matrix-vector products. A recurrent net (the GRU
of `pvvjax dynamic`'s `rnn` model) carries a state from window to window: `step(state, x)`
advances it by one window from `initial_state()`. This file depends on
NumPy only and can be copied next to the parameter file (`pvvjax export` does that).
"""

from __future__ import annotations

import json
import os

import numpy as np

__all__ = ["NumpyNet", "read_npz", "write_npz"]


def read_npz(path) -> tuple[dict, dict]:
    """Parameters and metadata of a pvvjax `.npz` parameter file (no pickle)."""
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(str(z["__meta__"])) if "__meta__" in z.files else {}
        out: dict = {}
        for key in z.files:
            if key == "__meta__":
                continue
            *parents, leaf = key.split("/")
            node = out
            for p in parents:
                node = node.setdefault(p, {})
            node[leaf] = z[key]
    for group in ("layers", "masks"):  # sequences were flattened with integer keys
        if group in out:
            out[group] = tuple(out[group][str(i)] for i in range(len(out[group])))
    return out, meta


def write_npz(path, params: dict, meta: dict):
    """Write parameters (nested dicts and tuples of arrays) and JSON metadata as a `.npz`
    that `read_npz` reads, atomically (a temporary file renamed)."""
    flat = {}

    def walk(node, key):
        if isinstance(node, dict):
            for k, v in node.items():
                walk(v, f"{key}/{k}" if key else str(k))
        elif isinstance(node, (tuple, list)):
            for i, v in enumerate(node):
                walk(v, f"{key}/{i}")
        else:
            flat[key] = np.asarray(node)

    walk(params, "")
    flat["__meta__"] = np.array(json.dumps(meta))
    path = str(path)
    tmp = path + ".tmp.npz"
    np.savez(tmp, **flat)
    os.replace(tmp, path)


class NumpyNet:
    """An MLP, RBF or GRU network evaluated with NumPy (float64). An MLP of several outputs
    (`n_out`, e.g. one per pilot-floor axis) returns one value per output. A GRU (`kind`
    "gru", `stateful`) reads its inputs window by window; called on a sequence it runs along
    the sequence's second-to-last axis from a zero state, as `dynamics.rnn_apply` does.

    Args:
        params: parameter dict (as saved by pvvjax).
        meta: metadata (input names, architecture), optional.
    """

    def __init__(self, params: dict, meta: dict | None = None):
        self.meta = dict(meta or {})
        self.inputs = list(self.meta.get("inputs", []))
        p = {k: v for k, v in params.items()}
        if "rnn" in p:
            self._gru(p)
            return
        in_mask = np.asarray(p["in_mask"], np.float64) > 0
        self.n_in = int(in_mask.sum())
        shift = np.asarray(p["x_shift"], np.float64)[in_mask]
        scale = np.asarray(p["x_scale"], np.float64)[in_mask]
        self.y_shift, self.y_scale = np.asarray(p["y_shift"], np.float64), np.asarray(p["y_scale"], np.float64)
        self.n_out = int(self.y_shift.size) if self.y_shift.ndim else 1
        if "layers" in p:
            self.kind = "mlp"
            masks = [np.asarray(m) > 0 for m in p["masks"]] + [np.ones(self.n_out, bool)]
            keep_in = in_mask
            self.w, self.b = [], []
            for layer, keep_out in zip(p["layers"], masks):
                self.w.append(np.asarray(layer["w"], np.float64)[np.ix_(keep_in, keep_out)])
                self.b.append(np.asarray(layer["b"], np.float64)[keep_out])
                keep_in = keep_out
            # fold input standardisation into the first layer, output scaling into the last
            self.b[0] = self.b[0] - (shift / scale) @ self.w[0]
            self.w[0] = self.w[0] / scale[:, None]
            if self.y_shift.ndim:  # several outputs: (h, A) and (A,)
                self.w[-1] = self.w[-1] * self.y_scale
                self.b[-1] = self.b[-1] * self.y_scale + self.y_shift
            else:
                self.w[-1] = self.w[-1][:, 0] * float(self.y_scale)
                self.b[-1] = float(self.b[-1][0] * self.y_scale + self.y_shift)
            self._buf = [np.empty(w.shape[1]) for w in self.w[:-1]]  # single-sample scratch
        else:
            self.kind = "rbf"
            self.centers = np.asarray(p["centers"], np.float64)[:, in_mask]
            self.inv2w2 = 0.5 / np.exp(2 * np.asarray(p["log_width"], np.float64))
            self.shift, self.scale = shift, scale
            self.wo = np.asarray(p["w"], np.float64) * float(self.y_scale)
            self.bo = float(p["b"]) * float(self.y_scale) + float(self.y_shift)

    def _gru(self, p: dict):
        """A GRU of `dynamics.Recurrent`'s variables with its standardisation folded in:
        one (n_in, 3H) input kernel and bias for the reset, update and candidate gates, the
        (H, 2H) recurrent kernel of the reset and update gates, the candidate's (H, H) kernel
        and bias, and a (H,) readout in g."""
        self.kind = "gru"
        cell, dense = p["rnn"]["GRUCell_0"], p["rnn"]["Dense_0"]
        f = lambda a: np.asarray(a, np.float64)  # noqa: E731
        shift, scale = f(p["x_shift"]), f(p["x_scale"])
        w_i = np.concatenate([f(cell[g]["kernel"]) for g in ("ir", "iz", "in")], axis=1)
        b_i = np.concatenate([f(cell[g]["bias"]) for g in ("ir", "iz", "in")])
        self.w_i, self.b_i = w_i / scale[:, None], b_i - (shift / scale) @ w_i
        self.w_h = np.concatenate([f(cell["hr"]["kernel"]), f(cell["hz"]["kernel"])], axis=1)
        self.w_hn, self.b_hn = f(cell["hn"]["kernel"]), f(cell["hn"]["bias"])
        y_scale, y_shift = float(f(p["y_scale"])), float(f(p["y_shift"]))
        self.w_out = f(dense["kernel"])[:, 0] * y_scale
        self.b_out = float(f(dense["bias"])[0]) * y_scale + y_shift
        self.n_in, self.n_out, self.hidden = self.w_i.shape[0], 1, self.w_hn.shape[0]

    @property
    def stateful(self) -> bool:
        """Whether the net carries a state from one window to the next (a GRU)."""
        return self.kind == "gru"

    def initial_state(self) -> np.ndarray:
        """The state before the first window: (hidden,) zeros for a GRU, (0,) otherwise."""
        return np.zeros(self.hidden if self.stateful else 0)

    def step(self, state: np.ndarray, x: np.ndarray):
        """One window: (the next state, the prediction) from the state and (n_in,) inputs.
        A net without a state returns the state unchanged."""
        if not self.stateful:
            return state, self(x)
        return self._gru_step(state, np.asarray(x, np.float64))

    def _gru_step(self, h, x):
        """flax's `GRUCell`: r, z = σ(x W_i + h W_h), n = tanh(x W_in + b + r (h W_hn + b_hn)),
        h' = (1 - z) n + z h; the readout is linear in h'."""
        H = self.hidden
        gi = x @ self.w_i + self.b_i  # (..., 3H)
        gh = h @ self.w_h
        r = 1.0 / (1.0 + np.exp(-(gi[..., :H] + gh[..., :H])))
        z = 1.0 / (1.0 + np.exp(-(gi[..., H:2 * H] + gh[..., H:])))
        n = np.tanh(gi[..., 2 * H:] + r * (h @ self.w_hn + self.b_hn))
        h = (1.0 - z) * n + z * h
        return h, h @ self.w_out + self.b_out

    @classmethod
    def load(cls, path) -> "NumpyNet":
        return cls(*read_npz(path))

    def predict1(self, x: np.ndarray):
        """One prediction from a float64 (n_in,) array, with no allocation (the simulator
        frame path; MLP only): a float, or (n_out,) for several outputs."""
        h = x
        for w, b, buf in zip(self.w[:-1], self.b[:-1], self._buf):
            np.dot(h, w, out=buf)
            np.add(buf, b, out=buf)
            np.tanh(buf, out=buf)
            h = buf
        if self.n_out > 1:
            return h @ self.w[-1] + self.b[-1]
        return float(np.dot(h, self.w[-1])) + self.b[-1]

    def __call__(self, x):
        """Peak PVV (g) for inputs x: (n_in,) or (n, n_in), physical units, database order
        (with several outputs, a last axis of n_out); for a GRU, (..., W, n_in) sequences
        to (..., W)."""
        x = np.asarray(x, np.float64)
        if self.kind == "gru":  # (..., W, n_in): along W from a zero state
            h, out = np.zeros(x.shape[:-2] + (self.hidden,)), []
            for w in range(x.shape[-2]):
                h, y = self._gru_step(h, x[..., w, :])
                out.append(y)
            return np.stack(out, axis=-1)
        if self.kind == "mlp" and x.ndim == 1:
            return self.predict1(x)
        if self.kind == "rbf":
            z = (x - self.shift) / self.scale
            d2 = ((z[..., None, :] - self.centers) ** 2).sum(-1)
            return np.exp(-d2 * self.inv2w2) @ self.wo + self.bo
        h = x
        for w, b in zip(self.w[:-1], self.b[:-1]):
            h = np.tanh(h @ w + b)
        return h @ self.w[-1] + self.b[-1]
