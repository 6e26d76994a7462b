"""The workflow's decision rules: constants that no user tunes, each with why it has its value.

They were set on the hidden-effect benchmark (`research/`); docs/discovery-defaults.md gives
the evidence for each.
"""

# Replay windows of the workflow start every revolution: fine enough to place a transient's
# peak, and the selection and training strides below thin them where rows must be independent.
HOP_REVS = 1.0

# Every n-th window of a counter enters the selection (neighbouring windows overlap and say
# the same thing; the permutation test is by condition anyway).
SELECTION_STRIDE = 4

# Window nets train on every n-th fully weighted replay window of each counter: at a hop of
# one revolution and windows of 8, adjacent training windows overlap by nothing.
TRAIN_STRIDE = 8

# The smallest relative drop of the held-out residual error (by condition) that a candidate
# or a floor refinement must bring to be proposed.
MIN_GAIN = 0.02

# Once the best candidate is significant, the simplest within this many standard errors of its
# held-out error is named: a channel's window mean before its spread or knee.
PARSIMONY = 1.0

# Knees and products of the model's own inputs that join the selection's floor before any
# candidate is asked: a knee that a few hundred peaks did not teach the nets is the map's
# floor, and a channel that follows it would otherwise be named for it.
FLOOR_REFINEMENTS = 4

# Confirmed tries whose shrinks (over all windows) lie within this of the best are tied with
# it (the retraining's noise); also the rise over all windows a try may cause on its floor
# control where it gains twice `min_shrink` where it acts.
SHRINK_NOISE = 0.02

# A try not beaten at p < alpha is tied only if its shrink is at least this share of the
# best's: the sign-flip test measures how consistently the best wins, not by how much.
TIE_SHARE = 0.5

# Of two tied terms on different channels, the rival is named if its term keeps this much
# more of its coefficient on top of the named's model than the named's keeps on top of the
# rival's: two forms of one signal keep about the same, and which keeps more is noise.
ENCOMPASSING_MARGIN = 0.1

# Time constants of the lags of the model's prediction offered as candidates, s. A fitted τ at
# the largest is a smoother, not a lag.
LAG_TAUS = (0.25, 0.5, 1.0, 1.5, 2.0, 3.0)

# Quantiles of a channel where the candidate library places knees.
KNEE_QUANTILES = (0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.95)

# Further alignments of the candidates without a fitted parameter, s: the static map's offset
# matches the slow changes, and a transient reaches the vibration through the faster rotor
# response (about 0.5 s).
CANDIDATE_OFFSETS_S = (0.5,)

# The lag test: the time constants its window nets train through, s; the fast dynamics every
# campaign has (rotor inflow and wake settle within about a second), whose lags are the
# test's reference and not a discovery, s; Adam steps of the jointly learned lag.
LAG_TEST_TAUS = (1.0, 2.0, 3.0)
LAG_FAST_S = 1.0
LAG_LEARN_STEPS = 2000

# A band the selection proposed trains its gain in steps of 1 / GAIN_UNIT: Adam moves every
# parameter by about one step, and in unit steps the nets' many weights take the mode before
# the one gain grows. The probe's band, a forced guess without a test, trains in unit steps.
GAIN_UNIT = 10.0

# The probe's band confirms only if its retraining predicts better where the band acts at
# this level, by condition: a real mode acts on few conditions, so `alpha` would reject it.
PROBE_ALPHA = 0.05
