/* FMI 2.0 co-simulation interface of an hpsim model (docs/fmu.md).
 *
 * The model comes as CasADi-generated C: hp_step (one internal step of hpsim's compiled ROS2 solver: z, the
 * inputs at the step's start and end, pw -> z), hp_param (p -> pw: p and what depends on it alone, computed
 * once), hp_outputs (x, memory, u, p -> y), hp_init (p, u -> z at the start) and, with HP_NRUN > 0, hp_run
 * (p -> the calculated parameters). model.h gives the
 * sizes, the internal step HP_DT, the start values and which input is extrapolated with which rate input.
 *
 * Value references: 0 .. NP-1 the parameter vector p, NP .. NP+NU-1 the inputs u, then the outputs y.
 * fmi2DoStep takes a communication step that is a whole number of internal steps. Inside it the inputs are
 * extrapolated from when they were set: one with a rate partner (HP_RATE_OF, e.g. the deflection and its
 * rate) with that rate (and the rate's derivative, when the importer gives it), unless the importer gives the
 * input's own derivative (fmi2SetRealInputDerivatives, canInterpolateInputs), which then takes precedence;
 * an input with neither is held. The outputs read after a step use
 * the inputs extrapolated to that time.
 * The FMU state (fmi2GetFMUstate / serialization) is the time, z, u and p: a restored state reproduces the
 * following steps bit for bit.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"
#include "model.h"

typedef long long casadi_int;     /* CasADi's default integer type in generated code */
typedef int (*hp_fn)(const double **arg, double **res, casadi_int *iw, double *w, int mem);
typedef int (*hp_work_fn)(casadi_int *sz_arg, casadi_int *sz_res, casadi_int *sz_iw, casadi_int *sz_w);

int hp_step(const double **arg, double **res, casadi_int *iw, double *w, int mem);
int hp_step_work(casadi_int *sz_arg, casadi_int *sz_res, casadi_int *sz_iw, casadi_int *sz_w);
int hp_param(const double **arg, double **res, casadi_int *iw, double *w, int mem);
int hp_param_work(casadi_int *sz_arg, casadi_int *sz_res, casadi_int *sz_iw, casadi_int *sz_w);
int hp_outputs(const double **arg, double **res, casadi_int *iw, double *w, int mem);
int hp_outputs_work(casadi_int *sz_arg, casadi_int *sz_res, casadi_int *sz_iw, casadi_int *sz_w);
int hp_init(const double **arg, double **res, casadi_int *iw, double *w, int mem);
int hp_init_work(casadi_int *sz_arg, casadi_int *sz_res, casadi_int *sz_iw, casadi_int *sz_w);
#if HP_NRUN > 0
int hp_run(const double **arg, double **res, casadi_int *iw, double *w, int mem);
int hp_run_work(casadi_int *sz_arg, casadi_int *sz_res, casadi_int *sz_iw, casadi_int *sz_w);
#endif

enum { MODE_INSTANTIATED, MODE_INIT, MODE_STEP, MODE_TERMINATED, MODE_ERROR };

typedef struct {           /* what fmi2GetFMUstate saves */
    double t;
    double z[HP_NZ];
    double u[HP_NU];
    double p[HP_NP];
    double u_time[HP_NU];  /* when each input was set: it is extrapolated from then */
    double du[HP_NU];      /* the input derivatives set by fmi2SetRealInputDerivatives (0 unless set) */
    int has_du[HP_NU];     /* a derivative was set since the input was last set */
    int started;           /* z holds a state (initialisation done) */
} HpState;

typedef struct {
    fmi2CallbackFunctions cb;
    char name[256];
    int logging;
    int mode;
    HpState s;
    double y[HP_NY];
    int y_valid;
    double U[HP_NU];
    double U1[HP_NU];
    double pw[HP_NPW];     /* hp_param(p), recomputed whenever p may have changed */
    double z_next[HP_NZ];
    const double **arg;
    double **res;
    casadi_int *iw;
    double *w;
} Instance;

static void logmsg(Instance *c, fmi2Status status, const char *category, const char *fmt, ...) {
    char buf[1024];
    va_list ap;
    if (!c || !c->cb.logger) return;
    if (status == fmi2OK && !c->logging) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    c->cb.logger(c->cb.componentEnvironment, c->name, status, category, "%s", buf);
}

static void grow(casadi_int *a, casadi_int *r, casadi_int *i, casadi_int *w, hp_work_fn f) {
    casadi_int sa, sr, si, sw;
    f(&sa, &sr, &si, &sw);
    if (sa > *a) *a = sa;
    if (sr > *r) *r = sr;
    if (si > *i) *i = si;
    if (sw > *w) *w = sw;
}

static int call(Instance *c, hp_fn f, const double **in, int n_in, double **out, int n_out) {
    int k;
    for (k = 0; k < n_in; k++) c->arg[k] = in[k];
    for (k = 0; k < n_out; k++) c->res[k] = out[k];
    return f(c->arg, c->res, c->iw, c->w, 0);
}

static int all_finite(const double *v, int n) {
    int k;
    for (k = 0; k < n; k++) if (!isfinite(v[k])) return 0;
    return 1;
}

/* input j `tau` seconds after the FMU's time, from when it was set: with its own derivative when the importer
   gave one, else along its rate partner (and the rate's derivative, when given), else held */
static double input_at(const Instance *c, int j, double tau) {
    double since = c->s.t - c->s.u_time[j] + tau;
    int r = HP_RATE_OF[j];
    if (c->s.has_du[j]) return c->s.u[j] + since * c->s.du[j];
    if (r >= 0) return c->s.u[j] + since * (c->s.u[r] + 0.5 * since * c->s.du[r]);
    return c->s.u[j];
}

/* the calculated parameters and the state at the start, from p and u */
static fmi2Status start_state(Instance *c) {
#if HP_NRUN > 0
    double run[HP_NRUN];
    const double *in_run[1];
    double *out_run[1];
    int k;
    in_run[0] = c->s.p;
    out_run[0] = run;
    if (call(c, hp_run, in_run, 1, out_run, 1)) return fmi2Error;
    for (k = 0; k < HP_NRUN; k++) c->s.p[HP_RUN_INDEX[k]] = run[k];
#endif
    {
        const double *in[2];
        double *out[1];
        in[0] = c->s.p;
        in[1] = c->s.u;
        out[0] = c->s.z;
        if (call(c, hp_init, in, 2, out, 1)) return fmi2Error;
    }
    {
        const double *in[1];
        double *out[1];
        in[0] = c->s.p;
        out[0] = c->pw;
        if (call(c, hp_param, in, 1, out, 1)) return fmi2Error;
    }
    if (!all_finite(c->s.z, HP_NZ)) {
        logmsg(c, fmi2Error, "logStatusError", "the start state is not finite: check the parameters");
        return fmi2Error;
    }
    c->s.started = 1;
    c->y_valid = 0;
    return fmi2OK;
}

static fmi2Status update_outputs(Instance *c) {
    const double *in[4];
    double *out[1];
    int j;
    if (c->y_valid) return fmi2OK;
    if (!c->s.started && start_state(c) != fmi2OK) return fmi2Error;
    /* the inputs now: one with a rate extrapolated from when it was set, as inside fmi2DoStep */
    for (j = 0; j < HP_NU; j++) c->U[j] = input_at(c, j, 0.0);
    in[0] = c->s.z;             /* x */
    in[1] = c->s.z + HP_NX;     /* solver memory */
    in[2] = c->U;
    in[3] = c->s.p;
    out[0] = c->y;
    if (call(c, hp_outputs, in, 4, out, 1)) return fmi2Error;
    c->y_valid = 1;
    return fmi2OK;
}

static void reset(Instance *c) {
    memset(&c->s, 0, sizeof c->s);
    memcpy(c->s.p, HP_P_START, sizeof c->s.p);
    memcpy(c->s.u, HP_U_START, sizeof c->s.u);
    c->y_valid = 0;
    c->mode = MODE_INSTANTIATED;
}

/* ---------------------------------------------------------------------------------------------- */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t n, const fmi2String cats[]) {
    (void)n; (void)cats;
    ((Instance *)comp)->logging = loggingOn;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String resourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Instance *c;
    casadi_int sa = 0, sr = 0, si = 0, sw = 0;
    (void)resourceLocation; (void)visible;
    if (!functions || !functions->allocateMemory || !functions->freeMemory) return NULL;
    if (fmuType != fmi2CoSimulation) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                              "this FMU supports co-simulation only");
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, HP_GUID) != 0) {
        if (functions->logger)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                              "wrong GUID %s (expected %s)", fmuGUID ? fmuGUID : "(null)", HP_GUID);
        return NULL;
    }
    c = (Instance *)functions->allocateMemory(1, sizeof(Instance));
    if (!c) return NULL;
    c->cb = *functions;
    snprintf(c->name, sizeof c->name, "%s", instanceName ? instanceName : "hpsim");
    c->logging = loggingOn;
    grow(&sa, &sr, &si, &sw, hp_step_work);
    grow(&sa, &sr, &si, &sw, hp_outputs_work);
    grow(&sa, &sr, &si, &sw, hp_param_work);
    grow(&sa, &sr, &si, &sw, hp_init_work);
#if HP_NRUN > 0
    grow(&sa, &sr, &si, &sw, hp_run_work);
#endif
    c->arg = (const double **)functions->allocateMemory((size_t)sa + 1, sizeof(double *));
    c->res = (double **)functions->allocateMemory((size_t)sr + 1, sizeof(double *));
    c->iw = (casadi_int *)functions->allocateMemory((size_t)si + 1, sizeof(casadi_int));
    c->w = (double *)functions->allocateMemory((size_t)sw + 1, sizeof(double));
    if (!c->arg || !c->res || !c->iw || !c->w) return NULL;
    reset(c);
    return c;
}

void fmi2FreeInstance(fmi2Component comp) {
    Instance *c = (Instance *)comp;
    fmi2CallbackFreeMemory release;
    if (!c) return;
    release = c->cb.freeMemory;
    release((void *)c->arg);
    release(c->res);
    release(c->iw);
    release(c->w);
    release(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    Instance *c = (Instance *)comp;
    int j;
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    c->s.t = startTime;
    for (j = 0; j < HP_NU; j++) c->s.u_time[j] = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp) {
    ((Instance *)comp)->mode = MODE_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp) {
    Instance *c = (Instance *)comp;
    if (start_state(c) != fmi2OK) {
        c->mode = MODE_ERROR;
        return fmi2Error;
    }
    c->mode = MODE_STEP;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component comp) {
    ((Instance *)comp)->mode = MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component comp) {
    reset((Instance *)comp);
    return fmi2OK;
}

/* ---------------------------------------------------------------------------------------------- */
fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Instance *c = (Instance *)comp;
    size_t k;
    for (k = 0; k < nvr; k++) {
        fmi2ValueReference r = vr[k];
        if (r < HP_NP) {
            if (c->mode == MODE_INIT || c->mode == MODE_INSTANTIATED) {
#if HP_NRUN > 0
                if (!c->s.started && start_state(c) != fmi2OK) return fmi2Error;
#endif
            }
            value[k] = c->s.p[r];
        } else if (r < HP_NP + HP_NU) {
            value[k] = c->s.u[r - HP_NP];
        } else if (r < HP_NP + HP_NU + HP_NY) {
            if (update_outputs(c) != fmi2OK) return fmi2Error;
            value[k] = c->y[r - HP_NP - HP_NU];
        } else {
            logmsg(c, fmi2Error, "logStatusError", "fmi2GetReal: unknown value reference %u", (unsigned)r);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Instance *c = (Instance *)comp;
    size_t k;
    for (k = 0; k < nvr; k++) {
        fmi2ValueReference r = vr[k];
        if (r < HP_NP) {
            if (c->mode == MODE_STEP) {
                logmsg(c, fmi2Error, "logStatusError",
                       "fmi2SetReal: parameter %u is fixed after initialisation", (unsigned)r);
                return fmi2Error;
            }
            if (!(value[k] >= HP_P_MIN[r] && value[k] <= HP_P_MAX[r])) {   /* also NaN */
                logmsg(c, fmi2Error, "logStatusError",
                       "fmi2SetReal: parameter %u = %g is outside its allowed range [%g, %g] "
                       "(modelDescription.xml min/max); not set", (unsigned)r, value[k], HP_P_MIN[r], HP_P_MAX[r]);
                return fmi2Error;
            }
            c->s.p[r] = value[k];
            c->s.started = 0;
        } else if (r < HP_NP + HP_NU) {
            if (!isfinite(value[k])) {
                logmsg(c, fmi2Error, "logStatusError", "fmi2SetReal: input %u = %g is not a finite number; not set",
                       (unsigned)r, value[k]);
                return fmi2Error;
            }
            c->s.u[r - HP_NP] = value[k];
            c->s.u_time[r - HP_NP] = c->s.t;
            c->s.du[r - HP_NP] = 0.0;
            c->s.has_du[r - HP_NP] = 0;
            if (c->mode != MODE_STEP) c->s.started = 0;
        } else {
            logmsg(c, fmi2Error, "logStatusError", "fmi2SetReal: value reference %u cannot be set", (unsigned)r);
            return fmi2Error;
        }
    }
    c->y_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    (void)c; (void)vr; (void)value;
    return nvr ? fmi2Error : fmi2OK;
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    (void)c; (void)vr; (void)value;
    return nvr ? fmi2Error : fmi2OK;
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    (void)c; (void)vr; (void)value;
    return nvr ? fmi2Error : fmi2OK;
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    (void)c; (void)vr; (void)value;
    return nvr ? fmi2Error : fmi2OK;
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    (void)c; (void)vr; (void)value;
    return nvr ? fmi2Error : fmi2OK;
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    (void)c; (void)vr; (void)value;
    return nvr ? fmi2Error : fmi2OK;
}

/* ---------------------------------------------------------------------------------------------- */
fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *state) {
    Instance *c = (Instance *)comp;
    HpState *s = (HpState *)*state;
    if (!s) {
        s = (HpState *)c->cb.allocateMemory(1, sizeof(HpState));
        if (!s) return fmi2Error;
        *state = s;
    }
    *s = c->s;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate state) {
    Instance *c = (Instance *)comp;
    if (!state) return fmi2Error;
    c->s = *(HpState *)state;
    c->y_valid = 0;
    if (c->s.started) {     /* the parameters' derived values for the restored p */
        const double *in[1];
        double *out[1];
        in[0] = c->s.p;
        out[0] = c->pw;
        if (call(c, hp_param, in, 1, out, 1)) return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *state) {
    Instance *c = (Instance *)comp;
    if (state && *state) {
        c->cb.freeMemory(*state);
        *state = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate state, size_t *size) {
    (void)comp; (void)state;
    *size = sizeof(HpState);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate state, fmi2Byte bytes[], size_t size) {
    (void)comp;
    if (!state || size < sizeof(HpState)) return fmi2Error;
    memcpy(bytes, state, sizeof(HpState));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte bytes[], size_t size, fmi2FMUstate *state) {
    Instance *c = (Instance *)comp;
    if (size != sizeof(HpState)) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2DeSerializeFMUstate: %u bytes, expected %u", (unsigned)size,
               (unsigned)sizeof(HpState));
        return fmi2Error;
    }
    if (!*state) {
        *state = c->cb.allocateMemory(1, sizeof(HpState));
        if (!*state) return fmi2Error;
    }
    memcpy(*state, bytes, sizeof(HpState));
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vU[], size_t nU,
                                        const fmi2ValueReference vK[], size_t nK, const fmi2Real dvK[],
                                        fmi2Real dvU[]) {
    (void)c; (void)vU; (void)nU; (void)vK; (void)nK; (void)dvK; (void)dvU;
    return fmi2Error;
}

/* ---------------------------------------------------------------------------------------------- */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    Instance *c = (Instance *)comp;
    size_t k;
    for (k = 0; k < nvr; k++) {
        if (vr[k] < HP_NP || vr[k] >= HP_NP + HP_NU || order[k] != 1) {
            logmsg(c, fmi2Error, "logStatusError",
                   "fmi2SetRealInputDerivatives: value reference %u order %d (first derivatives of inputs only)",
                   (unsigned)vr[k], (int)order[k]);
            return fmi2Error;
        }
        c->s.du[vr[k] - HP_NP] = value[k];
        c->s.has_du[vr[k] - HP_NP] = 1;
    }
    c->y_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)c; (void)vr; (void)nvr; (void)order; (void)value;
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real t, fmi2Real h, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *c = (Instance *)comp;
    double n_real = h / HP_DT;
    long n = (long)floor(n_real + 0.5), k;
    int j;
    const double *in[4];
    double *out[1];
    (void)noSetFMUStatePriorToCurrentPoint;
    if (c->mode != MODE_STEP) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2DoStep: not initialised");
        return fmi2Error;
    }
    if (!isfinite(t) || !isfinite(h)) {
        logmsg(c, fmi2Error, "logStatusError", "fmi2DoStep: the step's start %g s and size %g s must be finite",
               t, h);
        return fmi2Error;
    }
    if (n < 1 || fabs(n_real - (double)n) > 1e-6) {
        logmsg(c, fmi2Error, "logStatusError",
               "fmi2DoStep: the communication step %g s must be a whole multiple of the internal step %g s", h,
               HP_DT);
        return fmi2Error;
    }
    if (fabs(t - c->s.t) > 1e-9 * (1.0 + fabs(t))) {
        logmsg(c, fmi2Warning, "logStatusWarning", "fmi2DoStep: step starts at %.17g s, the FMU is at %.17g s", t,
               c->s.t);
    }
    in[0] = c->s.z;
    in[1] = c->U;
    in[2] = c->U1;
    in[3] = c->pw;
    out[0] = c->z_next;
    for (k = 0; k < n; k++) {
        for (j = 0; j < HP_NU; j++) {
            c->U[j] = input_at(c, j, (double)k * HP_DT);
            c->U1[j] = input_at(c, j, (double)(k + 1) * HP_DT);
        }
        if (call(c, hp_step, in, 4, out, 1) || !all_finite(c->z_next, HP_NZ)) {
            logmsg(c, fmi2Error, "logStatusError", "fmi2DoStep: the state is no longer finite at t = %g s",
                   c->s.t + (double)k * HP_DT);
            c->mode = MODE_ERROR;
            return fmi2Error;
        }
        memcpy(c->s.z, c->z_next, sizeof c->z_next);
    }
    c->s.t = t + h;
    c->y_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value) {
    if (s == fmi2LastSuccessfulTime) {
        *value = ((Instance *)comp)->s.t;
        return fmi2OK;
    }
    return fmi2Discard;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
