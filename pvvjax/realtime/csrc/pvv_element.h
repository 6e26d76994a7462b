/* pvv_element.h: the pvvjax real-time vibration element in C99 (written by `pvvjax export --format c`).
 *
 * One frame of flight state in, the peak @BLADES@/rev pilot-floor vertical vibration (PVV, g) and a
 * seat-shake sample out. It computes what the NumPy element (pvvjax.realtime.VibrationElement)
 * computes: windows of `window_revs` rotor revolutions every `hop_revs`, the inputs averaged over
 * the same window moved `offset_s` earlier (the sticks `stick_offset_s` more), the median of the
 * trained nets, inputs clipped to the training envelope and flagged, and a seat shake at the rotor
 * azimuth whose amplitude ramps over one hop. An element of a dynamic model (PVV_RESPONSE 1) passes
 * each window's median through a delay and a unit-gain second-order response along the window
 * times, as the NumPy element does. Nets of several outputs (PVV_N_OUT, one per pilot-floor axis)
 * give each seat axis its PVV and its shake (N/rev at the predicted amplitude and its phase, plus
 * the 1/rev of rotor track and balance); an axis the element does not predict stays 0. Inputs may be
 * rates (the backward difference of a feature's window average to the window before, per second,
 * 0 at the first window), and GRU nets carry their state from window to window.
 *
 * Needs <math.h> only. The element is one struct of fixed size: declare it static or allocate it
 * once (pvv_element_size() bytes); no call allocates memory.
 *
 *     static pvv_element el;
 *     pvv_settings s = pvv_default_settings();
 *     if (pvv_init(&el, &s) != PVV_OK) ...;       settings outside the limits below
 *     each frame:
 *         double ch[PVV_N_CHANNELS] = {airspeed_kt, gross_weight_lb, rotor_rpm, ...};
 *         pvv_output o = pvv_step(&el, time_s, azimuth_deg, ch);   azimuth NAN: integrate rotor_rpm
 *         shaker(o.shake_g);
 *     pvv_reset(&el) at a simulator reset.
 *
 * Source: @SOURCE@
 */
#ifndef PVV_ELEMENT_H
#define PVV_ELEMENT_H

#ifdef __cplusplus
extern "C" {
#endif

/* Channels of a frame, canonical units of the pvvjax data contract, in this order. */
#define PVV_N_CHANNELS 10
enum pvv_channel {
    PVV_AIRSPEED_KT = 0,      /* true airspeed, kt */
    PVV_GROSS_WEIGHT_LB = 1,  /* gross weight, lb */
    PVV_ROTOR_RPM = 2,        /* main-rotor speed, rpm */
    PVV_DENSITY_RATIO = 3,    /* air density / sea-level standard, - */
    PVV_PITCH_RATE_DPS = 4,   /* body pitch rate, deg/s */
    PVV_ROLL_ANGLE_DEG = 5,   /* roll attitude, deg */
    PVV_CLIMB_RATE_FPM = 6,   /* rate of climb, ft/min */
    PVV_COLLECTIVE_PCT = 7,   /* collective stick, % of travel */
    PVV_LATERAL_PCT = 8,      /* lateral cyclic, % of travel */
    PVV_LONGITUDINAL_PCT = 9  /* longitudinal cyclic, % of travel */
};

/* What the buffers were sized for: frames up to PVV_MAX_RATE_HZ at rotor speeds down to
 * PVV_MIN_RPM, windows up to PVV_MAX_WINDOW_REVS, offsets within +-PVV_MAX_OFFSET_S and
 * +-PVV_MAX_STICK_OFFSET_S. Faster frames or a slower rotor still run, but frames beyond
 * PVV_CAPACITY drop the oldest one and raise `overflow`. */
#define PVV_MAX_RATE_HZ @MAX_RATE_HZ@
#define PVV_MIN_RPM @MIN_RPM@
#define PVV_MIN_WINDOW_REVS @MIN_WINDOW_REVS@
#define PVV_MAX_WINDOW_REVS @MAX_WINDOW_REVS@
#define PVV_MAX_OFFSET_S @MAX_OFFSET_S@
#define PVV_MAX_STICK_OFFSET_S @MAX_STICK_OFFSET_S@
#define PVV_CAPACITY @CAPACITY@
/* Windows the dynamic response keeps for its delay (1 where the element has no response). */
#define PVV_HIST @HIST@
/* Outputs of every net: the pilot-floor axes the element predicts (@OUTPUTS@). */
#define PVV_N_OUT @N_OUT@
/* The nets whose median the element predicts, and the largest state one carries (a GRU's
 * units; 1 where none carries one). */
#define PVV_N_NETS @N_NETS@
#define PVV_STATE @STATE@

#define PVV_OK 0
#define PVV_EBADSETTINGS (-1)

/* Settings a host may change at init (pvv_default_settings() gives the exported ones). */
typedef struct pvv_settings {
    double offset_s;        /* input-to-vibration offset, s, within +-PVV_MAX_OFFSET_S */
    double stick_offset_s;  /* the sticks' extra offset (a stick lag), s */
    double window_revs;     /* window length, revolutions, PVV_MIN_WINDOW_REVS..PVV_MAX_WINDOW_REVS */
    double hop_revs;        /* window spacing (update interval), revolutions, (0, window_revs] */
    int clip;               /* 1: clip inputs to the training envelope (always flagged), 0: only flag */
} pvv_settings;

/* One frame's outputs. */
typedef struct pvv_output {
    double pvv_g;           /* PVV of the latest ready window, g (0 before the first) */
    double shake_g;         /* seat-shake sample: amplitude x cos(N psi + phase) + harmonics, g */
    double amplitude_g;     /* the shake's amplitude, ramped over one hop from the previous value, g */
    double window_time_s;   /* centre time of the window pvv_g belongs to, s (NAN before the first) */
    double pvv_x_g, pvv_y_g, pvv_z_g;        /* each seat axis's N/rev amplitude (0: not predicted), g */
    double shake_x_g, shake_y_g, shake_z_g;  /* each seat axis's shake: x forward, y right, z vertical, g */
    int ready;              /* a window has been predicted since the last reset */
    int out_of_envelope;    /* an input of that window lay outside the training envelope */
    int rejected;           /* this frame was ignored: a non-finite value or a time not advancing */
    int overflow;           /* frames came faster than the buffers were sized for (since reset) */
} pvv_output;

/* The element's state: read it through pvv_output only. */
typedef struct pvv_element {
    pvv_settings s;
    int n;                  /* frames stored */
    double t[PVV_CAPACITY], r[PVV_CAPACITY], x[PVV_CAPACITY][PVV_N_CHANNELS];
    double az, rpm_last, start, pvv[PVV_N_OUT], prev[PVV_N_OUT], ramp_rev, wtime;
    long j;
    int has_az, has_start, flag, ready, dropped, overflow;
    /* the dynamic response: recent windows' static values, the first, and the state */
    double hist_t[PVV_HIST], hist_u[PVV_HIST][PVV_N_OUT], first_t, first_u[PVV_N_OUT], dyn_t;
    double dyn_ud[PVV_N_OUT], dyn_y[PVV_N_OUT], dyn_v[PVV_N_OUT];
    int nh, has_dyn;
    /* the recurrent nets' states, and the latest window's centre time and features (for rates) */
    double net_state[PVV_N_NETS][PVV_STATE], last_tc, last_feats[PVV_N_CHANNELS + 2];
    int has_last;
} pvv_element;

/* The settings the element was exported with. */
pvv_settings pvv_default_settings(void);

/* Take settings and reset. Returns PVV_OK, or PVV_EBADSETTINGS (element unchanged) for a
 * value that is not finite or outside the limits above. */
int pvv_init(pvv_element *e, const pvv_settings *s);

/* Forget every frame (a new run or a simulator reset); the settings stay. */
void pvv_reset(pvv_element *e);

/* Advance by one frame: time_s (s, increasing), azimuth_deg of the reference blade (deg; NAN to
 * integrate channels[PVV_ROTOR_RPM] instead), channels in enum pvv_channel order. */
pvv_output pvv_step(pvv_element *e, double time_s, double azimuth_deg, const double channels[PVV_N_CHANNELS]);

/* sizeof(pvv_element), for hosts that allocate it. */
unsigned long pvv_element_size(void);

#ifdef __cplusplus
}
#endif

#endif /* PVV_ELEMENT_H */
