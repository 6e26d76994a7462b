/* pvv_element.c: the pvvjax real-time vibration element in C99 (see pvv_element.h).
 *
 * Frame by frame the same arithmetic as pvvjax.realtime.VibrationElement (NumPy), in double
 * precision: frames are stored as they come in fixed arrays, frames left of every future input
 * window are dropped after each window, and each window's inputs are hat-weighted averages of
 * the stored frames. Source: @SOURCE@
 */
#include <math.h>

#include "pvv_element.h"

#define PVV_PI 3.14159265358979323846
#define PVV_KT_TO_FT_S (6076.12 / 3600.0)

/* ------------------------------------------------------------------ exported constants */
@CONSTANTS@
/* ------------------------------------------------------------------ the nets */
@NETS@
/* ------------------------------------------------------------------ helpers */

/* First index i of increasing xp[0..n) with xp[i] >= x (numpy.searchsorted, side left). */
static int search_left(const double *xp, int n, double x)
{
    int lo = 0, hi = n;
    while (lo < hi) {
        int mid = lo + (hi - lo) / 2;
        if (xp[mid] < x) lo = mid + 1; else hi = mid;
    }
    return lo;
}

/* Linear interpolation on increasing xp, extrapolating with the end segments (n >= 2). */
static double interp(double x, const double *xp, const double *fp, int n)
{
    int i = search_left(xp, n, x);
    if (i < 1) i = 1;
    if (i > n - 1) i = n - 1;
    return fp[i - 1] + (x - xp[i - 1]) * ((fp[i] - fp[i - 1]) / (xp[i] - xp[i - 1]));
}

/* Part of a sample's hat inside a window edge (u in hat half-widths); NaN stays NaN. */
static double edge_weight(double u)
{
    double v = u < -1.0 ? -1.0 : (u > 1.0 ? 1.0 : u);
    return v < 0.0 ? 0.5 * (1.0 + v) * (1.0 + v) : 1.0 - 0.5 * (1.0 - v) * (1.0 - v);
}

static int finite(double v) { return !isnan(v) && !isinf(v); }

/* Move frames [k, n) to the front (forward copy: the ranges may overlap). */
static void shift_left(pvv_element *e, int k)
{
    int i, c, n = e->n - k;
    for (i = 0; i < n; i++) {
        e->t[i] = e->t[i + k];
        e->r[i] = e->r[i + k];
        for (c = 0; c < PVV_N_CHANNELS; c++) e->x[i][c] = e->x[i + k][c];
    }
    e->n = n;
    e->dropped = 1;
}

/* Drop the frames before index `keep_from` but one (never the first two: they define window 0). */
static void drop_before(pvv_element *e, int keep_from)
{
    if (keep_from > 2) shift_left(e, keep_from - 1);
}

/* Output i's shake amplitude now, ramped over one hop from the previous window's value. */
static double ramped(const pvv_element *e, int i)
{
    double frac = (e->r[e->n - 1] - e->ramp_rev) / e->s.hop_revs;
    frac = frac < 0.0 ? 0.0 : (frac > 1.0 ? 1.0 : frac);
    return e->prev[i] + (e->pvv[i] - e->prev[i]) * frac;
}

static pvv_output output(const pvv_element *e, int rejected)
{
    pvv_output o;
    double psi, pvv_axis[3] = {0.0, 0.0, 0.0}, shake_axis[3] = {0.0, 0.0, 0.0};
    int i, k;
    o.rejected = rejected;
    o.overflow = e->overflow;
    if (e->n == 0) {
        o.pvv_g = o.shake_g = o.amplitude_g = 0.0;
        o.pvv_x_g = o.pvv_y_g = o.pvv_z_g = o.shake_x_g = o.shake_y_g = o.shake_z_g = 0.0;
        o.window_time_s = NAN;
        o.ready = o.out_of_envelope = 0;
        return o;
    }
    psi = 2.0 * PVV_PI * e->r[e->n - 1];
    for (i = 0; i < PVV_N_OUT; i++) {
        double amp = ramped(e, i);
        double shake = amp * cos(PVV_BLADES * psi + PVV_PHASE[i]) + PVV_ONCE_G[i] * cos(psi + PVV_ONCE_PHASE[i]);
        for (k = 0; k < PVV_N_HARMONICS; k++)
            if (PVV_HARMONIC_OUT[k] == i)
                shake += PVV_HARMONIC_RATIO[k] * amp * cos(PVV_HARMONIC_K[k] * psi + PVV_HARMONIC_PHASE[k]);
        pvv_axis[PVV_OUT_AXIS[i]] = e->pvv[i];
        shake_axis[PVV_OUT_AXIS[i]] = shake;
        if (i == 0) {
            o.pvv_g = e->pvv[0];
            o.shake_g = shake;
            o.amplitude_g = amp;
        }
    }
    o.pvv_x_g = pvv_axis[0];
    o.pvv_y_g = pvv_axis[1];
    o.pvv_z_g = pvv_axis[2];
    o.shake_x_g = shake_axis[0];
    o.shake_y_g = shake_axis[1];
    o.shake_z_g = shake_axis[2];
    o.ready = e->ready;
    o.window_time_s = e->wtime;
    o.out_of_envelope = e->flag;
    return o;
}

/* The nets' inputs from window-averaged channels at centre time tc: features and their rates
 * (the backward difference to the latest window), envelope flag, clipping. */
static int net_inputs(pvv_element *e, const double *x, double tc, double *z)
{
    double feats[2 * (PVV_N_CHANNELS + 2)];
    double v = x[PVV_AIRSPEED_KT] * PVV_KT_TO_FT_S;
    const int nf = PVV_N_CHANNELS + 2;
    int i, flag = 0;
    for (i = 0; i < PVV_N_CHANNELS; i++) feats[i] = x[i];
    feats[PVV_N_CHANNELS] = v / (x[PVV_ROTOR_RPM] * 2.0 * PVV_PI / 60.0 * PVV_ROTOR_RADIUS_FT);
    feats[PVV_N_CHANNELS + 1] = ((1.0 + x[PVV_PITCH_RATE_DPS] * (PVV_PI / 180.0) * v / PVV_G_FT_S2)
                                 / cos(x[PVV_ROLL_ANGLE_DEG] * (PVV_PI / 180.0)));
    for (i = 0; i < nf; i++) {
        feats[nf + i] = e->has_last && tc > e->last_tc ? (feats[i] - e->last_feats[i]) / (tc - e->last_tc) : 0.0;
        e->last_feats[i] = feats[i];
    }
    e->last_tc = tc;
    e->has_last = 1;
    for (i = 0; i < PVV_N_INPUTS; i++) {
        double lo = PVV_LO[i], hi = PVV_HI[i];
        double tol = 1e-9 * (1.0 + (fabs(lo) > fabs(hi) ? fabs(lo) : fabs(hi)));
        z[i] = feats[PVV_INPUT_FEATURE[i]];
        if (z[i] < lo - tol || z[i] > hi + tol) flag = 1;
        if (e->s.clip) z[i] = z[i] < lo ? lo : (z[i] > hi ? hi : z[i]);
    }
    return flag;
}

/* The nets' median, output by output (each recurrent net's state advanced by one window). */
static void median_prediction(pvv_element *e, const double *z, double *pred)
{
    double outs[PVV_N_NETS][PVV_N_OUT], p[PVV_N_NETS];
    int i, k, o;
    for (k = 0; k < PVV_N_NETS; k++) PVV_NETS[k](z, e->net_state[k], outs[k]);
    for (o = 0; o < PVV_N_OUT; o++) {
        for (k = 0; k < PVV_N_NETS; k++) {  /* insertion sort as they come */
            double v = outs[k][o];
            for (i = k; i > 0 && p[i - 1] > v; i--) p[i] = p[i - 1];
            p[i] = v;
        }
        pred[o] = PVV_N_NETS % 2 ? p[PVV_N_NETS / 2] : 0.5 * (p[PVV_N_NETS / 2 - 1] + p[PVV_N_NETS / 2]);
    }
}

#if PVV_RESPONSE
/* Drop the oldest window of the response's history. */
static void drop_oldest(pvv_element *e)
{
    int i, o;
    for (i = 1; i < e->nh; i++) {
        e->hist_t[i - 1] = e->hist_t[i];
        for (o = 0; o < PVV_N_OUT; o++) e->hist_u[i - 1][o] = e->hist_u[i][o];
    }
    e->nh -= 1;
}

/* The response's outputs at window time tc from the static values u (one per output, replaced
 * in place): the delayed input interpolated among recent windows (the first value held before
 * it), then one trapezoidal (Tustin) step of y'' + 2 zeta wn y' + wn^2 y = wn^2 u, from rest at
 * the first window. */
static void respond(pvv_element *e, double *u, double tc)
{
    const double w2 = PVV_OMEGA_N * PVV_OMEGA_N, c = 2.0 * PVV_ZETA * PVV_OMEGA_N;
    double td = tc - PVV_DELAY_S, a, det;
    int o, j;
    if (e->nh == 0) {
        e->first_t = tc;
        for (o = 0; o < PVV_N_OUT; o++) e->first_u[o] = u[o];
    }
    if (e->nh == PVV_HIST) {  /* windows faster than sized for: lose the oldest, say so */
        drop_oldest(e);
        e->overflow = 1;
    }
    e->hist_t[e->nh] = tc;
    for (o = 0; o < PVV_N_OUT; o++) e->hist_u[e->nh][o] = u[o];
    e->nh += 1;
    while (e->nh > 2 && e->hist_t[1] <= td) drop_oldest(e);  /* older windows lie before every future delay */
    j = search_left(e->hist_t, e->nh, td);  /* as interp(): the segment [j - 1, j], end segments extended */
    j = j < 1 ? 1 : (j > e->nh - 1 ? e->nh - 1 : j);
    a = 0.5 * (tc - e->dyn_t);
    det = 1.0 + a * c + a * a * w2;
    for (o = 0; o < PVV_N_OUT; o++) {
        double x0 = e->hist_t[j - 1], x1 = e->hist_t[j], f0 = e->hist_u[j - 1][o], f1 = e->hist_u[j][o];
        double ud = td <= e->first_t ? e->first_u[o] : f0 + (td - x0) * ((f1 - f0) / (x1 - x0));
        double r0, r1;
        if (!e->has_dyn) {
            e->dyn_ud[o] = e->dyn_y[o] = u[o] = ud;
            e->dyn_v[o] = 0.0;
            continue;
        }
        r0 = e->dyn_y[o] + a * e->dyn_v[o];
        r1 = e->dyn_v[o] - a * w2 * e->dyn_y[o] - a * c * e->dyn_v[o] + a * w2 * (e->dyn_ud[o] + ud);
        e->dyn_y[o] = u[o] = ((1.0 + a * c) * r0 + a * r1) / det;
        e->dyn_v[o] = (-a * w2 * r0 + r1) / det;
        e->dyn_ud[o] = ud;
    }
    e->has_dyn = 1;
    e->dyn_t = tc;
}

#endif

/* The window [a, b)'s time weighted as its channel means (the offline analysis's centre time). */
static double centre_time(const pvv_element *e, double a, double b)
{
    const int n = e->n;
    const double *r = e->r;
    double wsum = 0.0, tw = 0.0;
    int i;
    for (i = 0; i < n; i++) {
        double h = i == 0 ? (e->dropped ? NAN : r[1] - r[0])
                 : (i == n - 1 ? r[n - 1] - r[n - 2] : 0.5 * ((r[i] - r[i - 1]) + (r[i + 1] - r[i])));
        double w = h * edge_weight((r[i] - a) / h) * edge_weight((b - r[i]) / h);
        if (!finite(w) || w == 0.0) continue;
        wsum += w;
        tw += w * e->t[i];
    }
    return tw / wsum;
}
/* Predict the next window if the stored frames cover it; returns 1 if one was predicted. */
static int try_window(pvv_element *e)
{
    const int n = e->n;
    const double *t = e->t, *r = e->r;
    double a = e->start + e->s.hop_revs * (double)e->j, b = a + e->s.window_revs;
    double taus[2], lo[2], hi[2], mean[2][PVV_N_CHANNELS], z[PVV_N_INPUTS];
    double t_a, t_b, drmax, need, t_next, maxtau;
    int ntau, k, i, c, flag;

    if (r[n - 1] <= b) return 0;
    t_a = interp(a, r, t, n);
    t_b = interp(b, r, t, n);
    taus[0] = e->s.offset_s;
    taus[1] = e->s.offset_s + e->s.stick_offset_s;
    ntau = e->s.stick_offset_s != 0.0 ? 2 : 1;
    for (k = 0; k < ntau; k++) {
        lo[k] = interp(t_a - taus[k], t, r, n);
        hi[k] = interp(t_b - taus[k], t, r, n);
    }
    /* Every hat touching the input windows must be complete: two samples past the last edge. */
    drmax = r[1] - r[0];
    for (i = 2; i < n; i++) if (r[i] - r[i - 1] > drmax) drmax = r[i] - r[i - 1];
    need = (ntau == 2 && hi[1] > hi[0] ? hi[1] : hi[0]) + 2.0 * drmax;
    if (r[n - 1] <= need || n < 3) return 0;

    for (k = 0; k < ntau; k++) {
        double wsum = 0.0;
        for (c = 0; c < PVV_N_CHANNELS; c++) mean[k][c] = 0.0;
        for (i = 0; i < n; i++) {
            /* half-way to each neighbour; the first frame's left neighbour may have been dropped */
            double h = i == 0 ? (e->dropped ? NAN : r[1] - r[0])
                     : (i == n - 1 ? r[n - 1] - r[n - 2] : 0.5 * ((r[i] - r[i - 1]) + (r[i + 1] - r[i])));
            double w = h * edge_weight((r[i] - lo[k]) / h) * edge_weight((hi[k] - r[i]) / h);
            if (!finite(w) || w == 0.0) continue;
            wsum += w;
            for (c = 0; c < PVV_N_CHANNELS; c++) mean[k][c] += w * e->x[i][c];
        }
        for (c = 0; c < PVV_N_CHANNELS; c++) mean[k][c] /= wsum;
    }
    if (ntau == 2) {
        mean[0][PVV_COLLECTIVE_PCT] = mean[1][PVV_COLLECTIVE_PCT];
        mean[0][PVV_LATERAL_PCT] = mean[1][PVV_LATERAL_PCT];
        mean[0][PVV_LONGITUDINAL_PCT] = mean[1][PVV_LONGITUDINAL_PCT];
    }
    {
        double pred[PVV_N_OUT], tc = centre_time(e, a, b);
        int o;
        flag = net_inputs(e, mean[0], tc, z);
        median_prediction(e, z, pred);
#if PVV_RESPONSE
        respond(e, pred, tc);
#endif
        for (o = 0; o < PVV_N_OUT; o++) {
            e->prev[o] = e->ready ? ramped(e, o) : pred[o];
            e->pvv[o] = pred[o];
        }
    }
    e->flag = flag;
    e->ready = 1;
    e->ramp_rev = r[n - 1];
    e->wtime = 0.5 * (t_a + t_b);
    e->j += 1;
    /* Frames left of every future input window are no longer needed. */
    maxtau = 0.0;
    for (k = 0; k < ntau; k++) if (taus[k] > maxtau) maxtau = taus[k];
    t_next = interp(e->start + e->s.hop_revs * (double)e->j, r, t, n) - maxtau;
    drop_before(e, search_left(t, n, t_next) - 2);
    return 1;
}

/* ------------------------------------------------------------------ API */

pvv_settings pvv_default_settings(void)
{
    pvv_settings s;
    s.offset_s = PVV_DEFAULT_OFFSET_S;
    s.stick_offset_s = PVV_DEFAULT_STICK_OFFSET_S;
    s.window_revs = PVV_DEFAULT_WINDOW_REVS;
    s.hop_revs = PVV_DEFAULT_HOP_REVS;
    s.clip = 1;
    return s;
}

unsigned long pvv_element_size(void) { return (unsigned long)sizeof(pvv_element); }

void pvv_reset(pvv_element *e)
{
    int o;
    e->n = 0;
    e->az = e->rpm_last = e->start = e->ramp_rev = 0.0;
    for (o = 0; o < PVV_N_OUT; o++) e->pvv[o] = e->prev[o] = 0.0;
    e->wtime = NAN;
    e->j = 0;
    e->has_az = e->has_start = e->flag = e->ready = e->dropped = e->overflow = 0;
    e->nh = e->has_dyn = e->has_last = 0;
    for (o = 0; o < PVV_N_NETS; o++) {
        int k;
        for (k = 0; k < PVV_STATE; k++) e->net_state[o][k] = 0.0;
    }
}

int pvv_init(pvv_element *e, const pvv_settings *s)
{
    if (!(finite(s->offset_s) && fabs(s->offset_s) <= PVV_MAX_OFFSET_S
          && finite(s->stick_offset_s) && fabs(s->stick_offset_s) <= PVV_MAX_STICK_OFFSET_S
          && s->window_revs >= PVV_MIN_WINDOW_REVS && s->window_revs <= PVV_MAX_WINDOW_REVS
          && s->hop_revs > 0.0 && s->hop_revs <= s->window_revs))
        return PVV_EBADSETTINGS;
    e->s = *s;
    pvv_reset(e);
    return PVV_OK;
}

pvv_output pvv_step(pvv_element *e, double time_s, double azimuth_deg, const double channels[PVV_N_CHANNELS])
{
    int c, use_az = !isnan(azimuth_deg), bad = !finite(time_s) || (e->n > 0 && time_s <= e->t[e->n - 1]);
    double r, rpm = channels[PVV_ROTOR_RPM];
    for (c = 0; c < PVV_N_CHANNELS; c++) bad = bad || !finite(channels[c]);
    if (use_az) bad = bad || !finite(azimuth_deg);
    if (bad) return output(e, 1);

    if (e->n == 0) {
        r = use_az ? azimuth_deg / 360.0 : 0.0;
    } else if (use_az && e->has_az) {
        double d = azimuth_deg - e->az;
        r = e->r[e->n - 1] + (d - 360.0 * nearbyint(d / 360.0)) / 360.0;  /* unwrapped */
    } else {  /* the rotor speed, integrated by the trapezoidal rule */
        r = e->r[e->n - 1] + 0.5 * (e->rpm_last + rpm) / 60.0 * (time_s - e->t[e->n - 1]);
    }
    e->az = azimuth_deg;
    e->has_az = use_az;
    e->rpm_last = rpm;
    if (e->n == PVV_CAPACITY) {  /* faster than sized for: lose the oldest frame, say so */
        shift_left(e, 1);
        e->overflow = 1;
    }
    e->t[e->n] = time_s;
    e->r[e->n] = r;
    for (c = 0; c < PVV_N_CHANNELS; c++) e->x[e->n][c] = channels[c];
    e->n += 1;
    if (e->n == 2 && !e->has_start) {
        e->start = e->r[0] - 0.5 * (e->r[1] - e->r[0]);
        e->has_start = 1;
    }
    if (e->has_start)
        while (try_window(e)) {
        }
    return output(e, 0);
}
