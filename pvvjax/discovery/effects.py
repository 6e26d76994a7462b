"""Candidate effects: the operators of data-contract §3 that turn a record's channels into
candidate features for the discovery workflow.

Each operator is a pure function of sample-level arrays (one record, or vmapped), smooth in
its parameters so that a time constant or a knee can be fitted by gradient:

- `input`: a channel as is;
- `rate`, `abs_rate`: its time derivative (central differences on the actual sample times)
  and the derivative's magnitude (smoothed at zero);
- `lag`: a first-order lag with time constant τ, exact for piecewise-constant input between
  samples, computed as a linear recurrence by `lax.associative_scan` (log-depth, not a
  sample-by-sample loop);
- `threshold`: a hinge above (or below) a knee, softened over `softness`;
- `product`: of two channels;
- `resonance`: a band of a channel (rotor speed) around a centre, Gaussian or Lorentzian
  (`band`);
- `window`: an analysis-window artefact: the spread of a channel inside each window
  (computed from window means of x and x², see `window_spread`).

Window averages of a candidate come from the same window sums as the replay
(`harmonics.window_sums`), so a candidate enters a model exactly like a state channel.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = [
    "OPERATORS",
    "abs_rate",
    "band",
    "lag",
    "product",
    "rate",
    "resonance",
    "threshold",
    "window_spread",
]

OPERATORS = ("input", "rate", "abs_rate", "lag", "threshold", "product", "resonance", "window")
BAND_SHAPES = ("gaussian", "lorentzian")


@jax.jit  # one program per shape, inside another program or not
def rate(x, time):
    """dx/dt by central differences on the sample times (one-sided at the ends).

    Args:
        x, time: (T,) samples and their times, s (increasing).

    Returns:
        (T,) derivative per second.
    """
    xp = jnp.concatenate([x[:1], x, x[-1:]])
    tp = jnp.concatenate([time[:1], time, time[-1:]])
    lo, hi = jnp.arange(x.shape[0]), jnp.arange(x.shape[0]) + 2
    return (xp[hi] - xp[lo]) / (tp[hi] - tp[lo])


@jax.jit  # one program per shape, inside another program or not
def abs_rate(x, time, smooth=1e-6):
    """|dx/dt|, smoothed at zero (√(r² + s²) − s) so that it is differentiable there."""
    r = rate(x, time)
    return jnp.sqrt(r * r + smooth * smooth) - smooth


@jax.jit  # one program per shape, inside another program or not
def lag(x, time, tau_s):
    """First-order lag y' = (x − y)/τ, started at rest on the first sample.

    Exact for an input held between samples: y_n = a_n y_{n−1} + (1 − a_n) x_n with
    a_n = exp(−Δt_n / τ). The recurrence is solved by an associative scan over the pairs
    (a_n, (1 − a_n) x_n), so its cost is log-depth and it differentiates in τ.

    Args:
        x, time: (T,) samples and their times, s. tau_s: time constant, s (> 0).

    Returns:
        (T,) lagged signal.
    """
    dt = jnp.diff(time, prepend=time[:1])
    a = jnp.exp(-dt / tau_s)
    b = (1.0 - a) * x
    b = b.at[0].set(x[0])  # at rest: y_0 = x_0

    def combine(left, right):  # (a1, b1) then (a2, b2): y -> a2 (a1 y + b1) + b2
        a1, b1 = left
        a2, b2 = right
        return a1 * a2, a2 * b1 + b2

    return jax.lax.associative_scan(combine, (a, b))[1]


def threshold(x, knee, above: bool = True, softness=1e-3):
    """Hinge max(0, x − knee) (or max(0, knee − x)), softened as softness·softplus(·/softness)."""
    u = (x - knee) if above else (knee - x)
    return softness * jax.nn.softplus(u / softness)


def product(x1, x2):
    """The product of two channels."""
    return x1 * x2


def band(u, shape: str = "gaussian", xp=None):
    """A resonance band of the normalised distance u = (x − centre)/width: "gaussian"
    exp(−½u²), or "lorentzian" 1/(1 + u²), the line shape of a lightly damped mode, whose
    tails reach settings several widths away (rotor speeds a few percent apart).

    Args:
        u: array. shape: one of `BAND_SHAPES`. xp: the array module (default `jnp`; `np`
            for float64 tables).

    Returns:
        array like u, 1 at the centre.
    """
    if shape == "gaussian":
        return (jnp if xp is None else xp).exp(-0.5 * u * u)
    if shape == "lorentzian":
        return 1.0 / (1.0 + u * u)
    raise ValueError(f"band shape must be one of {BAND_SHAPES}, got {shape!r}")


def resonance(x, center, width, shape: str = "gaussian"):
    """A band of a channel around a centre (`band`), e.g. of rotor speed near a resonance."""
    return band((x - center) / width, shape)


def window_spread(mean_x, mean_x2):
    """Standard deviation of a channel inside each window, from its window means of x and x²."""
    return jnp.sqrt(jnp.maximum(mean_x2 - mean_x * mean_x, 0.0))
