/* fmi2_pvv_element.c: the pvvjax vibration element as an FMI 2.0 co-simulation unit.
 *
 * Written from the FMI 2.0.x standard (fmi-standard.org); the types and function signatures
 * below are the standard's. Each fmi2DoStep(t, h) is one element frame at time t with the
 * inputs set for that communication point; the outputs read after it belong to that frame.
 * Value references are those of modelDescription.xml (written by `pvvjax export --format fmu`).
 */
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "pvv_element.h"

/* ------------------------------------------------------------------ FMI 2.0 types */
typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;

typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated } fmi2StatusKind;

typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
typedef void *(*fmi2CallbackAllocateMemory)(size_t, size_t);
typedef void (*fmi2CallbackFreeMemory)(void *);
typedef void (*fmi2StepFinished)(fmi2ComponentEnvironment, fmi2Status);

typedef struct {
    const fmi2CallbackLogger logger;
    const fmi2CallbackAllocateMemory allocateMemory;
    const fmi2CallbackFreeMemory freeMemory;
    const fmi2StepFinished stepFinished;
    const fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

#if defined(_WIN32)
#define FMI2_EXPORT __declspec(dllexport)
#elif defined(__GNUC__)
#define FMI2_EXPORT __attribute__((visibility("default")))
#else
#define FMI2_EXPORT
#endif

/* ------------------------------------------------------------------ value references */
/* Real: 0..9 the channels (enum pvv_channel), 10 azimuth_deg; 20..29 outputs; 40..43 parameters.
 * Boolean: 30..33 output flags; 44 azimuth_input, 45 clip. */
enum {
    VR_AZIMUTH = 10,
    VR_PVV = 20, VR_SHAKE = 21, VR_AMPLITUDE = 22, VR_WINDOW_TIME = 23,
    VR_PVV_X = 24, VR_PVV_Y = 25, VR_PVV_Z = 26, VR_SHAKE_X = 27, VR_SHAKE_Y = 28, VR_SHAKE_Z = 29,
    VR_READY = 30, VR_OUT_OF_ENVELOPE = 31, VR_REJECTED = 32, VR_OVERFLOW = 33,
    VR_OFFSET = 40, VR_STICK_OFFSET = 41, VR_WINDOW = 42, VR_HOP = 43,
    VR_AZIMUTH_INPUT = 44, VR_CLIP = 45
};

#define GUID "@GUID@"

typedef struct {
    pvv_element el;
    pvv_settings s;
    pvv_output out;
    double ch[PVV_N_CHANNELS], azimuth;
    int azimuth_input, running, logging;
    char name[128];
    const fmi2CallbackFunctions *cb;
} instance;

static void say(instance *c, fmi2Status status, const char *msg)
{
    if (c->cb && c->cb->logger && (c->logging || status >= fmi2Error))
        c->cb->logger(c->cb->componentEnvironment, c->name, status, status >= fmi2Error ? "logStatusError" : "log",
                      msg);
}

static void defaults(instance *c)
{
    int i;
    c->s = pvv_default_settings();
    for (i = 0; i < PVV_N_CHANNELS; i++) c->ch[i] = 0.0;
    c->ch[PVV_DENSITY_RATIO] = 1.0;
    c->ch[PVV_ROTOR_RPM] = PVV_MIN_RPM * 2.0;
    c->azimuth = 0.0;
    c->azimuth_input = 1;
    c->running = 0;
    pvv_init(&c->el, &c->s);
    c->out.pvv_g = c->out.shake_g = c->out.amplitude_g = 0.0;
    c->out.pvv_x_g = c->out.pvv_y_g = c->out.pvv_z_g = c->out.shake_x_g = c->out.shake_y_g = c->out.shake_z_g = 0.0;
    c->out.window_time_s = NAN;
    c->out.ready = c->out.out_of_envelope = c->out.rejected = c->out.overflow = 0;
}

/* ------------------------------------------------------------------ life cycle */

FMI2_EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
FMI2_EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

FMI2_EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                          fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                                          fmi2Boolean visible, fmi2Boolean loggingOn)
{
    instance *c;
    size_t k;
    (void)fmuResourceLocation;
    (void)visible;
    if (!functions || !functions->allocateMemory || !functions->freeMemory) return NULL;
    if (fmuType != fmi2CoSimulation || !fmuGUID || strcmp(fmuGUID, GUID) != 0) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                              "pvv_element: not this FMU's GUID, or not co-simulation");
        return NULL;
    }
    c = (instance *)functions->allocateMemory(1, sizeof(instance));
    if (!c) return NULL;
    for (k = 0; instanceName && instanceName[k] && k + 1 < sizeof c->name; k++) c->name[k] = instanceName[k];
    c->name[k] = '\0';
    c->cb = functions;
    c->logging = loggingOn;
    defaults(c);
    return c;
}

FMI2_EXPORT void fmi2FreeInstance(fmi2Component c)
{
    instance *i = (instance *)c;
    if (i) i->cb->freeMemory(i);
}

FMI2_EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t n, const fmi2String cats[])
{
    (void)n;
    (void)cats;
    ((instance *)c)->logging = loggingOn;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                                           fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    (void)c; (void)toleranceDefined; (void)tolerance; (void)startTime; (void)stopTimeDefined; (void)stopTime;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    (void)c;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    instance *i = (instance *)c;
    if (pvv_init(&i->el, &i->s) != PVV_OK) {
        say(i, fmi2Error, "pvv_element: offset_s, stick_offset_s, window_revs or hop_revs outside the element's "
                          "limits (see the parameters' min and max)");
        return fmi2Error;
    }
    i->running = 1;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2Terminate(fmi2Component c)
{
    ((instance *)c)->running = 0;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2Reset(fmi2Component c)
{
    defaults((instance *)c);
    return fmi2OK;
}

/* ------------------------------------------------------------------ values */

FMI2_EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[])
{
    instance *i = (instance *)c;
    size_t k;
    for (k = 0; k < n; k++) {
        unsigned v = vr[k];
        if (v < PVV_N_CHANNELS) value[k] = i->ch[v];
        else if (v == VR_AZIMUTH) value[k] = i->azimuth;
        else if (v == VR_PVV) value[k] = i->out.pvv_g;
        else if (v == VR_SHAKE) value[k] = i->out.shake_g;
        else if (v == VR_AMPLITUDE) value[k] = i->out.amplitude_g;
        else if (v == VR_WINDOW_TIME) value[k] = i->out.window_time_s;
        else if (v == VR_PVV_X) value[k] = i->out.pvv_x_g;
        else if (v == VR_PVV_Y) value[k] = i->out.pvv_y_g;
        else if (v == VR_PVV_Z) value[k] = i->out.pvv_z_g;
        else if (v == VR_SHAKE_X) value[k] = i->out.shake_x_g;
        else if (v == VR_SHAKE_Y) value[k] = i->out.shake_y_g;
        else if (v == VR_SHAKE_Z) value[k] = i->out.shake_z_g;
        else if (v == VR_OFFSET) value[k] = i->s.offset_s;
        else if (v == VR_STICK_OFFSET) value[k] = i->s.stick_offset_s;
        else if (v == VR_WINDOW) value[k] = i->s.window_revs;
        else if (v == VR_HOP) value[k] = i->s.hop_revs;
        else {
            say(i, fmi2Error, "pvv_element: fmi2GetReal: unknown value reference");
            return fmi2Error;
        }
    }
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[])
{
    instance *i = (instance *)c;
    size_t k;
    for (k = 0; k < n; k++) {
        unsigned v = vr[k];
        if (v < PVV_N_CHANNELS) i->ch[v] = value[k];
        else if (v == VR_AZIMUTH) i->azimuth = value[k];
        else if (v >= VR_OFFSET && v <= VR_HOP && i->running) {
            say(i, fmi2Error, "pvv_element: parameters are fixed after initialization");
            return fmi2Error;
        }
        else if (v == VR_OFFSET) i->s.offset_s = value[k];
        else if (v == VR_STICK_OFFSET) i->s.stick_offset_s = value[k];
        else if (v == VR_WINDOW) i->s.window_revs = value[k];
        else if (v == VR_HOP) i->s.hop_revs = value[k];
        else {
            say(i, fmi2Error, "pvv_element: fmi2SetReal: not an input or parameter");
            return fmi2Error;
        }
    }
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[])
{
    instance *i = (instance *)c;
    size_t k;
    for (k = 0; k < n; k++) {
        unsigned v = vr[k];
        if (v == VR_READY) value[k] = i->out.ready;
        else if (v == VR_OUT_OF_ENVELOPE) value[k] = i->out.out_of_envelope;
        else if (v == VR_REJECTED) value[k] = i->out.rejected;
        else if (v == VR_OVERFLOW) value[k] = i->out.overflow;
        else if (v == VR_AZIMUTH_INPUT) value[k] = i->azimuth_input;
        else if (v == VR_CLIP) value[k] = i->s.clip;
        else {
            say(i, fmi2Error, "pvv_element: fmi2GetBoolean: unknown value reference");
            return fmi2Error;
        }
    }
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                      const fmi2Boolean value[])
{
    instance *i = (instance *)c;
    size_t k;
    for (k = 0; k < n; k++) {
        unsigned v = vr[k];
        if ((v == VR_AZIMUTH_INPUT || v == VR_CLIP) && i->running) {
            say(i, fmi2Error, "pvv_element: parameters are fixed after initialization");
            return fmi2Error;
        }
        if (v == VR_AZIMUTH_INPUT) i->azimuth_input = value[k] != 0;
        else if (v == VR_CLIP) i->s.clip = value[k] != 0;
        else {
            say(i, fmi2Error, "pvv_element: fmi2SetBoolean: not a parameter");
            return fmi2Error;
        }
    }
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[])
{
    (void)vr; (void)v;
    return n == 0 ? fmi2OK : (say((instance *)c, fmi2Error, "pvv_element: no Integer variables"), fmi2Error);
}

FMI2_EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[])
{
    (void)vr; (void)v;
    return n == 0 ? fmi2OK : (say((instance *)c, fmi2Error, "pvv_element: no Integer variables"), fmi2Error);
}

FMI2_EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[])
{
    (void)vr; (void)v;
    return n == 0 ? fmi2OK : (say((instance *)c, fmi2Error, "pvv_element: no String variables"), fmi2Error);
}

FMI2_EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[])
{
    (void)vr; (void)v;
    return n == 0 ? fmi2OK : (say((instance *)c, fmi2Error, "pvv_element: no String variables"), fmi2Error);
}

/* ------------------------------------------------------------------ stepping */

FMI2_EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real stepSize,
                                  fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    instance *i = (instance *)c;
    (void)stepSize;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!i->running) {
        say(i, fmi2Error, "pvv_element: fmi2DoStep before fmi2ExitInitializationMode");
        return fmi2Error;
    }
    i->out = pvv_step(&i->el, currentCommunicationPoint, i->azimuth_input ? i->azimuth : NAN, i->ch);
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2CancelStep(fmi2Component c)
{
    (void)c;
    return fmi2Error;
}

FMI2_EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    (void)c; (void)s;
    *value = fmi2OK;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

FMI2_EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

FMI2_EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

FMI2_EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

/* ------------------------------------------------------------------ not supported (see the capability flags) */

FMI2_EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s)
{
    (void)s;
    say((instance *)c, fmi2Error, "pvv_element: canGetAndSetFMUstate is false");
    return fmi2Error;
}

FMI2_EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s)
{
    (void)s;
    say((instance *)c, fmi2Error, "pvv_element: canGetAndSetFMUstate is false");
    return fmi2Error;
}

FMI2_EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s)
{
    (void)c; (void)s;
    return fmi2Error;
}

FMI2_EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *size)
{
    (void)c; (void)s; (void)size;
    return fmi2Error;
}

FMI2_EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t size)
{
    (void)c; (void)s; (void)b; (void)size;
    return fmi2Error;
}

FMI2_EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t size, fmi2FMUstate *s)
{
    (void)c; (void)b; (void)size; (void)s;
    return fmi2Error;
}

FMI2_EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                                    const fmi2ValueReference z[], size_t nz, const fmi2Real dv[],
                                                    fmi2Real dz[])
{
    (void)c; (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz;
    return fmi2Error;
}

FMI2_EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                                   const fmi2Integer order[], const fmi2Real value[])
{
    (void)c; (void)vr; (void)n; (void)order; (void)value;
    return fmi2Error;
}

FMI2_EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                                    const fmi2Integer order[], fmi2Real value[])
{
    (void)c; (void)vr; (void)n; (void)order; (void)value;
    return fmi2Error;
}
