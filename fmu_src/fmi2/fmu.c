/* The FMI 2.0 layer of KevlarTether: a thin skin over the physics (physics/tether.h) and the
 * CVODE wrapper (solver/integrator.h), for Co-Simulation and Model Exchange in one binary.
 *
 * - Variables: model_variables.h, generated from modelDescription.xml, maps every value reference
 *   onto the field of the same name in the physics structs (compile error if one is missing).
 * - A strict call-sequence state machine: a call in the wrong state, a bad argument or an
 *   out-of-range value returns fmi2Error with a message naming the function, variable and value.
 * - Logging only through the callback, filtered by category (errors are always reported).
 * - FMU state saved by value (no pointers inside); CVODE is re-initialised after a restore, and
 *   after a save as well, so that a restored copy and the original continue bit for bit alike.
 * - No global or static mutable data: instances never share state.
 */
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "model_variables.h"
#include "physics/tether.h"
#include "solver/integrator.h"

/* compile-time agreement of modelDescription.xml and physics/tether.h (C99 static assertions) */
typedef char states_agree_with_model_description[KT_NUMBER_OF_STATES == TETHER_NUMBER_OF_STATES ? 1 : -1];
typedef char event_indicators_agree_with_model_description[KT_NUMBER_OF_EVENT_INDICATORS == TETHER_NUMBER_OF_EVENT_INDICATORS ? 1 : -1];

#define N_STATES TETHER_NUMBER_OF_STATES
#define N_EVENTS TETHER_NUMBER_OF_EVENT_INDICATORS

/* ---- state machine ------------------------------------------------------------------------- */
typedef enum {
    S_INSTANTIATED = 1 << 0,
    S_INIT = 1 << 1,
    S_EVENT = 1 << 2,          /* ME */
    S_CONTINUOUS = 1 << 3,     /* ME */
    S_STEP_COMPLETE = 1 << 4,  /* CS */
    S_STEP_FAILED = 1 << 5,    /* CS: the last step returned fmi2Discard */
    S_TERMINATED = 1 << 6,
    S_ERROR = 1 << 7,
    S_FATAL = 1 << 8
} fmu_state;

#define S_ANY_BUT_FATAL (S_INSTANTIATED | S_INIT | S_EVENT | S_CONTINUOUS | S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED | S_ERROR)
#define S_READABLE (S_INIT | S_EVENT | S_CONTINUOUS | S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED | S_ERROR)

static const char *state_name(int s)
{
    switch (s) {
    case S_INSTANTIATED: return "instantiated";
    case S_INIT: return "initialization mode";
    case S_EVENT: return "event mode";
    case S_CONTINUOUS: return "continuous-time mode";
    case S_STEP_COMPLETE: return "step complete";
    case S_STEP_FAILED: return "step failed";
    case S_TERMINATED: return "terminated";
    case S_ERROR: return "error";
    default: return "fatal";
    }
}

/* ---- log categories ------------------------------------------------------------------------ */
enum { LOG_EVENTS, LOG_WARNING, LOG_DISCARD, LOG_ERROR, LOG_FATAL, LOG_ALL, N_LOG_CATEGORIES };
static const char *const log_category_names[N_LOG_CATEGORIES] = {
    "logEvents", "logStatusWarning", "logStatusDiscard", "logStatusError", "logStatusFatal", "logAll"};

/* ---- instance ------------------------------------------------------------------------------ */
#define SNAPSHOT_MAGIC 0x4b544d31u /* "KTM1" */

/* everything that defines where a simulation stands: plain values, saved and restored by value */
typedef struct {
    uint32_t magic;
    uint32_t version;
    uint32_t size;
    char guid[40];
    int fmu_state;
    tether_model model;
    double y[N_STATES];
    double time;
    double last_successful_time;
    double start_time;
} snapshot;

/* first field of every instance: a pointer that does not carry it is not one of ours */
#define INSTANCE_MAGIC 0x4b54494eu /* "KTIN" */

typedef struct {
    uint32_t magic;
    fmi2Type type;
    char *instance_name;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    int logging_on;
    int category_on[N_LOG_CATEGORIES];
    int state;
    tether_model model;
    double y[N_STATES];
    double time, start_time, last_successful_time;
    int initialized;      /* tether_initialize has run on the current parameters */
    int needs_reset;      /* CS: restart CVODE before the next step */
    tether_integrator *integrator;
} instance;

/* the instance behind an fmi2Component, or NULL if it is NULL or not an instance of this FMU */
static instance *as_instance(fmi2Component comp)
{
    instance *c = (instance *)comp;
    return (c && c->magic == INSTANCE_MAGIC) ? c : NULL;
}

static void vlog(instance *c, fmi2Status status, int category, const char *fmt, va_list ap)
{
    if (!c || !c->logger) return;
    const int always = status == fmi2Error || status == fmi2Fatal;
    if (!always && !(c->logging_on && (c->category_on[category] || c->category_on[LOG_ALL]))) return;
    char buf[2048];
    vsnprintf(buf, sizeof buf, fmt, ap);
    /* the logger treats '#' specially (value references); there are none in our messages */
    c->logger(c->env, c->instance_name, status, log_category_names[category], "%s", buf);
}

static void log_event(instance *c, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vlog(c, fmi2OK, LOG_EVENTS, fmt, ap);
    va_end(ap);
}

static void log_warning(instance *c, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vlog(c, fmi2Warning, LOG_WARNING, fmt, ap);
    va_end(ap);
}

static void log_discard(instance *c, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vlog(c, fmi2Discard, LOG_DISCARD, fmt, ap);
    va_end(ap);
}

/* report an error and put the instance into the error state */
static fmi2Status fail(instance *c, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vlog(c, fmi2Error, LOG_ERROR, fmt, ap);
    va_end(ap);
    if (c && c->state != S_FATAL) c->state = S_ERROR;
    return fmi2Error;
}

/* report an error but leave the instance as it was (a refused FMU state changes nothing) */
static fmi2Status refuse(instance *c, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vlog(c, fmi2Error, LOG_ERROR, fmt, ap);
    va_end(ap);
    return fmi2Error;
}

static void integrator_log(void *ctx, const char *message) { log_event((instance *)ctx, "%s", message); }

/* check the call sequence and the instance pointer; returns nonzero if the call may proceed */
static int allowed(instance *c, const char *function, int states)
{
    if (!c) return 0;
    if (c->state & states) return 1;
    fail(c, "%s: not allowed in state '%s'", function, state_name(c->state));
    return 0;
}

#define CHECK_STATE(function, states)                                                             \
    do {                                                                                           \
        if (!c) return fmi2Error;                                                                  \
        if (!allowed(c, function, states)) return fmi2Error;                                       \
    } while (0)

#define CHECK_NOT_NULL(function, arg)                                                              \
    do {                                                                                           \
        if ((arg) == NULL) return fail(c, "%s: argument '%s' is NULL", function, #arg);          \
    } while (0)

static void set_start_values(instance *c)
{
    memset(&c->model, 0, sizeof c->model);
#define START_REAL(vr, id, name, kind, var, has_start, start, lo, hi) START_REAL_##kind(id, start)
#define START_REAL_KT_PARAM(id, start) c->model.p.id = start;
#define START_REAL_KT_INPUT(id, start) c->model.in.id = start;
#define START_REAL_KT_CALC(id, start)
#define START_REAL_KT_OUTPUT(id, start)
#define START_REAL_KT_LOCAL(id, start)
    KT_REAL_VARIABLES(START_REAL)
#define START_INT(vr, id, name, kind, var, start, lo, hi) c->model.p.id = start;
    KT_INTEGER_VARIABLES(START_INT)
#define START_BOOL(vr, id, name, kind, var, start) START_BOOL_##kind(id, start)
#define START_BOOL_KT_PARAM(id, start) c->model.p.id = start;
#define START_BOOL_KT_LOCAL(id, start)
    KT_BOOLEAN_VARIABLES(START_BOOL)
    memset(c->y, 0, sizeof c->y);
    c->time = c->start_time = c->last_successful_time = 0.0;
    c->initialized = 0;
    c->needs_reset = 1;
}

/* run the physics' initialisation on the current parameters, inputs and start time */
static fmi2Status initialize_model(instance *c, const char *function)
{
    char msg[1024];
    c->model.in.t_ref = c->time;
    if (tether_initialize(&c->model, c->time, c->y, msg, sizeof msg) != 0) return fail(c, "%s: %s", function, msg);
    const int n = tether_event_update(&c->model, c->time, c->y, msg, sizeof msg);
    if (n > 0) log_event(c, "%s", msg);
    c->initialized = 1;
    c->needs_reset = 1;
    if (tether_check_range(&c->model, c->time, c->y, msg, sizeof msg)) log_warning(c, "%s", msg);
    return fmi2OK;
}

static fmi2Status ensure_initialized(instance *c, const char *function)
{
    if (c->state == S_INIT && !c->initialized) return initialize_model(c, function);
    return fmi2OK;
}

/* ---- common functions ---------------------------------------------------------------------- */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2SetDebugLogging", S_ANY_BUT_FATAL);
    if (nCategories > 0 && !categories) return fail(c, "fmi2SetDebugLogging: nCategories = %zu but categories is NULL", nCategories);
    int on[N_LOG_CATEGORIES];
    memcpy(on, c->category_on, sizeof on);
    if (nCategories == 0) {
        for (int k = 0; k < N_LOG_CATEGORIES; ++k) on[k] = loggingOn ? 1 : 0;
    }
    for (size_t i = 0; i < nCategories; ++i) {
        int found = -1;
        for (int k = 0; k < N_LOG_CATEGORIES; ++k)
            if (categories[i] && strcmp(categories[i], log_category_names[k]) == 0) found = k;
        if (found < 0)
            return fail(c, "fmi2SetDebugLogging: unknown log category '%s' (known: logEvents, logStatusWarning, "
                        "logStatusDiscard, logStatusError, logStatusFatal, logAll)", categories[i] ? categories[i] : "(null)");
        on[found] = loggingOn ? 1 : 0;
    }
    memcpy(c->category_on, on, sizeof on);
    c->logging_on = loggingOn ? 1 : 0;
    if (!loggingOn && nCategories > 0) {
        /* switching some categories off keeps logging on for the others */
        for (int k = 0; k < N_LOG_CATEGORIES; ++k) c->logging_on |= c->category_on[k];
    }
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    (void)fmuResourceLocation;
    (void)visible;
    fmi2CallbackLogger logger = functions ? functions->logger : NULL;
    fmi2ComponentEnvironment env = functions ? functions->componentEnvironment : NULL;
    const char *name = instanceName ? instanceName : "(null)";
    if (!instanceName || !instanceName[0]) {
        if (logger) logger(env, name, fmi2Error, "logStatusError", "fmi2Instantiate: instanceName must be a non-empty string");
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, KT_MODEL_GUID) != 0) {
        if (logger)
            logger(env, name, fmi2Error, "logStatusError", "fmi2Instantiate: GUID '%s' does not match this FMU's '%s'",
                   fmuGUID ? fmuGUID : "(null)", KT_MODEL_GUID);
        return NULL;
    }
    if (fmuType != fmi2ModelExchange && fmuType != fmi2CoSimulation) {
        if (logger) logger(env, name, fmi2Error, "logStatusError", "fmi2Instantiate: fmuType = %d is neither fmi2ModelExchange (0) nor fmi2CoSimulation (1)", (int)fmuType);
        return NULL;
    }
    instance *c = (instance *)calloc(1, sizeof *c);
    if (!c) return NULL;
    c->instance_name = (char *)malloc(strlen(instanceName) + 1);
    if (!c->instance_name) { free(c); return NULL; }
    strcpy(c->instance_name, instanceName);
    c->magic = INSTANCE_MAGIC;
    c->type = fmuType;
    c->logger = logger;
    c->env = env;
    c->logging_on = loggingOn ? 1 : 0;
    for (int k = 0; k < N_LOG_CATEGORIES; ++k) c->category_on[k] = c->logging_on;
    set_start_values(c);
    c->state = S_INSTANTIATED;
    return c;
}

void fmi2FreeInstance(fmi2Component comp)
{
    instance *c = as_instance(comp);
    if (!c) return;
    integrator_free(c->integrator);
    free(c->instance_name);
    c->magic = 0; /* a second fmi2FreeInstance of this pointer is then refused, not a double free */
    free(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2SetupExperiment", S_INSTANTIATED);
    if (!isfinite(startTime)) return fail(c, "fmi2SetupExperiment: startTime = %g s is not finite", startTime);
    if (stopTimeDefined && !(stopTime >= startTime))
        return fail(c, "fmi2SetupExperiment: stopTime = %.17g s is before startTime = %.17g s", stopTime, startTime);
    if (toleranceDefined) {
        if (!(tolerance >= 1e-14 && tolerance <= 1e-2))
            return fail(c, "fmi2SetupExperiment: tolerance = %g outside [1e-14, 1e-2]", tolerance);
        c->model.p.rtol = tolerance;
    }
    c->time = c->start_time = c->last_successful_time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp)
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2EnterInitializationMode", S_INSTANTIATED);
    c->state = S_INIT;
    c->initialized = 0;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp)
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2ExitInitializationMode", S_INIT);
    if (!c->initialized && initialize_model(c, "fmi2ExitInitializationMode") != fmi2OK) return fmi2Error;
    if (c->type == fmi2CoSimulation) {
        char msg[1024];
        integrator_free(c->integrator);
        c->integrator = integrator_create(&c->model, integrator_log, c, msg, sizeof msg);
        if (!c->integrator) return fail(c, "fmi2ExitInitializationMode: %s", msg);
        c->needs_reset = 1;
        c->state = S_STEP_COMPLETE;
    } else {
        c->state = S_EVENT;
    }
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component comp)
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2Terminate", S_EVENT | S_CONTINUOUS | S_STEP_COMPLETE | S_STEP_FAILED);
    c->state = S_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component comp)
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2Reset", S_ANY_BUT_FATAL);
    integrator_free(c->integrator);
    c->integrator = NULL;
    set_start_values(c);
    c->state = S_INSTANTIATED;
    return fmi2OK;
}

/* ---- variables ----------------------------------------------------------------------------- */
static const char *real_name(fmi2ValueReference vr)
{
#define NAME_REAL(v, id, name, kind, var, hs, st, lo, hi) case v: return name;
    switch (vr) { KT_REAL_VARIABLES(NAME_REAL) default: return NULL; }
}

static void compute_outputs(instance *c, tether_outputs *o)
{
    /* Co-Simulation, inputs set since the last step: they switch the slack mode at once (the element
     * rig's tension feeds straight through from its elongation). The switch is made on a copy; the
     * next step makes it for good, so a master that tries inputs out leaves the memory untouched. */
    if (c->type == fmi2CoSimulation && c->needs_reset && c->state != S_INIT) {
        tether_model switched = c->model;
        tether_event_update(&switched, c->time, c->y, NULL, 0);
        tether_compute_outputs(&switched, c->time, c->y, o);
        return;
    }
    tether_compute_outputs(&c->model, c->time, c->y, o);
}

fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2GetReal", S_READABLE);
    if (nvr == 0) return fmi2OK;
    CHECK_NOT_NULL("fmi2GetReal", vr);
    CHECK_NOT_NULL("fmi2GetReal", value);
    if (ensure_initialized(c, "fmi2GetReal") != fmi2OK) return fmi2Error;
    tether_outputs o;
    compute_outputs(c, &o);
    for (size_t i = 0; i < nvr; ++i) {
        switch (vr[i]) {
#define GET_REAL(v, id, name, kind, var, hs, st, lo, hi) case v: value[i] = GET_REAL_##kind(id); break;
#define GET_REAL_KT_PARAM(id) c->model.p.id
#define GET_REAL_KT_INPUT(id) c->model.in.id
#define GET_REAL_KT_CALC(id) o.id
#define GET_REAL_KT_OUTPUT(id) o.id
#define GET_REAL_KT_LOCAL(id) o.id
            KT_REAL_VARIABLES(GET_REAL)
        default:
            return fail(c, "fmi2GetReal: no Real variable has value reference %u", (unsigned)vr[i]);
        }
        /* the element rig takes the elongation as an input; the other rigs compute it */
        if (real_name(vr[i]) && strcmp(real_name(vr[i]), "elongation") == 0 && c->model.p.rig != RIG_ELEMENT)
            value[i] = o.elongation;
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2GetInteger", S_READABLE);
    if (nvr == 0) return fmi2OK;
    CHECK_NOT_NULL("fmi2GetInteger", vr);
    CHECK_NOT_NULL("fmi2GetInteger", value);
    for (size_t i = 0; i < nvr; ++i) {
        switch (vr[i]) {
#define GET_INT(v, id, name, kind, var, st, lo, hi) case v: value[i] = c->model.p.id; break;
            KT_INTEGER_VARIABLES(GET_INT)
        default:
            return fail(c, "fmi2GetInteger: no Integer or Enumeration variable has value reference %u", (unsigned)vr[i]);
        }
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2GetBoolean", S_READABLE);
    if (nvr == 0) return fmi2OK;
    CHECK_NOT_NULL("fmi2GetBoolean", vr);
    CHECK_NOT_NULL("fmi2GetBoolean", value);
    if (ensure_initialized(c, "fmi2GetBoolean") != fmi2OK) return fmi2Error;
    tether_outputs o;
    compute_outputs(c, &o);
    (void)o;
    for (size_t i = 0; i < nvr; ++i) {
        switch (vr[i]) {
#define GET_BOOL(v, id, name, kind, var, st) case v: value[i] = GET_BOOL_##kind(id) ? fmi2True : fmi2False; break;
#define GET_BOOL_KT_PARAM(id) c->model.p.id
#define GET_BOOL_KT_LOCAL(id) o.id
            KT_BOOLEAN_VARIABLES(GET_BOOL)
        default:
            return fail(c, "fmi2GetBoolean: no Boolean variable has value reference %u", (unsigned)vr[i]);
        }
    }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2GetString", S_READABLE);
    (void)value;
    if (nvr == 0) return fmi2OK;
    CHECK_NOT_NULL("fmi2GetString", vr);
    return fail(c, "fmi2GetString: no String variable has value reference %u (the FMU has none)", (unsigned)vr[0]);
}

/* may a variable of this kind and variability be set in the current state? */
static int settable(instance *c, int kind, const char *variability)
{
    if (kind == KT_INPUT) return c->state & (S_INSTANTIATED | S_INIT | S_EVENT | S_CONTINUOUS | S_STEP_COMPLETE);
    if (kind == KT_PARAM && (strcmp(variability, "fixed") == 0 || strcmp(variability, "tunable") == 0))
        return c->state & (S_INSTANTIATED | S_INIT);
    return 0;
}

static const char *kind_name(int kind)
{
    switch (kind) {
    case KT_PARAM: return "parameter";
    case KT_CALC: return "calculated parameter";
    case KT_INPUT: return "input";
    case KT_OUTPUT: return "output";
    default: return "local variable";
    }
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2SetReal", S_INSTANTIATED | S_INIT | S_EVENT | S_CONTINUOUS | S_STEP_COMPLETE);
    if (nvr == 0) return fmi2OK;
    CHECK_NOT_NULL("fmi2SetReal", vr);
    CHECK_NOT_NULL("fmi2SetReal", value);
    for (size_t i = 0; i < nvr; ++i) {
        const double v = value[i];
        switch (vr[i]) {
#define SET_REAL(r, id, name, kind, var, hs, st, lo, hi)                                           \
    case r:                                                                                        \
        if (!settable(c, kind, var))                                                               \
            return fail(c, "fmi2SetReal: %s '%s' (variability %s) cannot be set in state '%s'",    \
                        kind_name(kind), name, var, state_name(c->state));                        \
        if (!isfinite(v) || v < (lo) || v > (hi))                                                  \
            return fail(c, "fmi2SetReal: %s = %.17g is outside its range [%g, %g]", name, v,        \
                        (double)(lo), (double)(hi));                                               \
        SET_REAL_##kind(id, v) break;
#define SET_REAL_KT_PARAM(id, v) c->model.p.id = v; c->initialized = 0;
#define SET_REAL_KT_INPUT(id, v)                                                                   \
    if (c->model.in.id != v) { c->model.in.id = v; c->needs_reset = 1; if (c->state == S_INIT) c->initialized = 0; }
#define SET_REAL_KT_CALC(id, v)
#define SET_REAL_KT_OUTPUT(id, v)
#define SET_REAL_KT_LOCAL(id, v)
            KT_REAL_VARIABLES(SET_REAL)
        default:
            return fail(c, "fmi2SetReal: no Real variable has value reference %u", (unsigned)vr[i]);
        }
        /* an interpolated input's polynomial starts where its value was set */
        const char *name = real_name(vr[i]);
        if (strcmp(name, "force") == 0 || strcmp(name, "load") == 0) c->model.in.t_ref = c->time;
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2SetInteger", S_INSTANTIATED | S_INIT | S_EVENT | S_CONTINUOUS | S_STEP_COMPLETE);
    if (nvr == 0) return fmi2OK;
    CHECK_NOT_NULL("fmi2SetInteger", vr);
    CHECK_NOT_NULL("fmi2SetInteger", value);
    for (size_t i = 0; i < nvr; ++i) {
        const int v = value[i];
        switch (vr[i]) {
#define SET_INT(r, id, name, kind, var, st, lo, hi)                                                \
    case r:                                                                                        \
        if (!settable(c, kind, var))                                                               \
            return fail(c, "fmi2SetInteger: %s '%s' (variability %s) cannot be set in state '%s'", \
                        kind_name(kind), name, var, state_name(c->state));                        \
        if (v < (lo) || v > (hi))                                                                  \
            return fail(c, "fmi2SetInteger: %s = %d is not one of its values %d..%d", name, v, lo, hi); \
        c->model.p.id = v;                                                                         \
        c->initialized = 0;                                                                        \
        break;
            KT_INTEGER_VARIABLES(SET_INT)
        default:
            return fail(c, "fmi2SetInteger: no Integer or Enumeration variable has value reference %u", (unsigned)vr[i]);
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2SetBoolean", S_INSTANTIATED | S_INIT | S_EVENT | S_CONTINUOUS | S_STEP_COMPLETE);
    if (nvr == 0) return fmi2OK;
    CHECK_NOT_NULL("fmi2SetBoolean", vr);
    CHECK_NOT_NULL("fmi2SetBoolean", value);
    for (size_t i = 0; i < nvr; ++i) {
        const int v = value[i] ? 1 : 0;
        switch (vr[i]) {
#define SET_BOOL(r, id, name, kind, var, st)                                                       \
    case r:                                                                                        \
        if (!settable(c, kind, var))                                                               \
            return fail(c, "fmi2SetBoolean: %s '%s' (variability %s) cannot be set in state '%s'", \
                        kind_name(kind), name, var, state_name(c->state));                        \
        SET_BOOL_##kind(id, v) break;
#define SET_BOOL_KT_PARAM(id, v) c->model.p.id = v; c->initialized = 0;
#define SET_BOOL_KT_LOCAL(id, v)
            KT_BOOLEAN_VARIABLES(SET_BOOL)
        default:
            return fail(c, "fmi2SetBoolean: no Boolean variable has value reference %u", (unsigned)vr[i]);
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2SetString", S_INSTANTIATED | S_INIT | S_EVENT | S_CONTINUOUS | S_STEP_COMPLETE);
    (void)value;
    if (nvr == 0) return fmi2OK;
    CHECK_NOT_NULL("fmi2SetString", vr);
    return fail(c, "fmi2SetString: no String variable has value reference %u (the FMU has none)", (unsigned)vr[0]);
}

/* ---- FMU state, by value ------------------------------------------------------------------- */
#define SNAPSHOT_VERSION 3u /* 3: the payload rig's carried and effective masses */
/* the run states an instance is in when its state is taken (never instantiated, never fatal) */
#define S_SAVED (S_INIT | S_EVENT | S_CONTINUOUS | S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED | S_ERROR)

static void take_snapshot(const instance *c, snapshot *s)
{
    memset(s, 0, sizeof *s);
    s->magic = SNAPSHOT_MAGIC;
    s->version = SNAPSHOT_VERSION;
    s->size = (uint32_t)sizeof *s;
    strncpy(s->guid, KT_MODEL_GUID, sizeof s->guid - 1);
    s->fmu_state = c->state;
    s->model = c->model;
    memcpy(s->y, c->y, sizeof s->y);
    s->time = c->time;
    s->last_successful_time = c->last_successful_time;
    s->start_time = c->start_time;
}

/* the header: magic number, version, size and GUID */
static int snapshot_valid(const snapshot *s)
{
    return s->magic == SNAPSHOT_MAGIC && s->version == SNAPSHOT_VERSION && s->size == sizeof *s &&
           memcmp(s->guid, KT_MODEL_GUID, sizeof KT_MODEL_GUID) == 0;
}

static int one_of_run_states(int state, int states)
{
    return state > 0 && (state & (state - 1)) == 0 && (state & states) != 0;
}

/* Everything a restored state holds, checked before any of it reaches the instance: the header,
 * the run state, every parameter and input finite and inside its declared range, every switch a
 * legal value, every state and time finite, the discrete memory consistent, and the parameters
 * passing the physics' own checks. Writes the field at fault and its value into msg. */
static int snapshot_check(const snapshot *s, char *msg, size_t len)
{
#define BAD(...) do { snprintf(msg, len, __VA_ARGS__); return -1; } while (0)
#define FINITE(value, what) do { if (!isfinite(value)) BAD("%s = %g is not finite", what, (double)(value)); } while (0)
    if (s->magic != SNAPSHOT_MAGIC) BAD("magic = 0x%08x, expected 0x%08x (not a KevlarTether state)", (unsigned)s->magic, SNAPSHOT_MAGIC);
    if (s->version != SNAPSHOT_VERSION) BAD("version = %u, this FMU reads version %u", (unsigned)s->version, SNAPSHOT_VERSION);
    if (s->size != sizeof *s) BAD("size = %u, expected %zu", (unsigned)s->size, sizeof *s);
    if (memcmp(s->guid, KT_MODEL_GUID, sizeof KT_MODEL_GUID) != 0) BAD("the GUID is not this FMU's %s", KT_MODEL_GUID);
    if (!one_of_run_states(s->fmu_state, S_SAVED))
        BAD("run state = %d is not one a saved instance may be in (initialization, event, continuous-time, "
            "step complete, step failed, terminated or error)", s->fmu_state);
    const tether_model *M = &s->model;
#define CHECK_REAL(vr, id, name, kind, var, hs, st, lo, hi) CHECK_REAL_##kind(id, name, lo, hi)
#define CHECK_REAL_RANGE(value, name, lo, hi)                                                      \
    if (!isfinite(value) || (value) < (lo) || (value) > (hi))                                      \
        BAD("%s = %.17g is outside its range [%g, %g]", name, (double)(value), (double)(lo), (double)(hi));
#define CHECK_REAL_KT_PARAM(id, name, lo, hi) CHECK_REAL_RANGE(M->p.id, name, lo, hi)
#define CHECK_REAL_KT_INPUT(id, name, lo, hi) CHECK_REAL_RANGE(M->in.id, name, lo, hi)
#define CHECK_REAL_KT_CALC(id, name, lo, hi)
#define CHECK_REAL_KT_OUTPUT(id, name, lo, hi)
#define CHECK_REAL_KT_LOCAL(id, name, lo, hi)
    KT_REAL_VARIABLES(CHECK_REAL)
#define CHECK_INT(vr, id, name, kind, var, st, lo, hi)                                             \
    if (M->p.id < (lo) || M->p.id > (hi)) BAD("%s = %d is not one of its values %d..%d", name, M->p.id, lo, hi);
    KT_INTEGER_VARIABLES(CHECK_INT)
#define CHECK_BOOL(vr, id, name, kind, var, st) CHECK_BOOL_##kind(id, name)
#define CHECK_BOOL_KT_PARAM(id, name) if (M->p.id != 0 && M->p.id != 1) BAD("%s = %d is not a Boolean (0 or 1)", name, M->p.id);
#define CHECK_BOOL_KT_LOCAL(id, name)
    KT_BOOLEAN_VARIABLES(CHECK_BOOL)
    char what[64];
    for (int k = 0; k < TETHER_INPUT_DERIVATIVE_ORDER; ++k) {
        snprintf(what, sizeof what, "d%d(force)/dt%d", k + 1, k + 1);
        FINITE(M->in.force_der[k], what);
        snprintf(what, sizeof what, "d%d(load)/dt%d", k + 1, k + 1);
        FINITE(M->in.load_der[k], what);
    }
    FINITE(M->in.t_ref, "input reference time");
#define STATE_NAME(index, state, derivative) #state,
    static const char *const state_names[N_STATES] = {KT_STATES(STATE_NAME)};
    for (int i = 0; i < N_STATES; ++i) FINITE(s->y[i], state_names[i]);
    FINITE(s->time, "time");
    FINITE(s->last_successful_time, "last successful time");
    FINITE(s->start_time, "start time");
    const tether_discrete *d = &M->d;
    if (d->taut != 0 && d->taut != 1) BAD("taut = %d is not 0 or 1", d->taut);
    if (d->warned_rising_limit != 0 && d->warned_rising_limit != 1) BAD("warned_rising_limit = %d is not 0 or 1", d->warned_rising_limit);
    FINITE(d->balance_elongation, "balance elongation");
    FINITE(d->carried_mass, "carried mass");
    FINITE(d->effective_mass, "effective mass");
    if (s->fmu_state != S_INIT && M->p.rig == RIG_PAYLOAD && !(d->effective_mass > 0.0 && d->carried_mass > 0.0))
        BAD("effective mass = %.17g kg, carried mass = %.17g kg: the payload rig needs both positive",
            d->effective_mass, d->carried_mass);
    if (isnan(d->rising_limit) || isnan(d->compression_limit)) BAD("the elastic law's rising range is NaN");
    const kawabata_memory *k = &d->kawabata;
    if (k->n < 0 || k->n > KAWABATA_MAX_REVERSALS) BAD("Kawabata reversal count = %d, expected 0..%d", k->n, KAWABATA_MAX_REVERSALS);
    if (k->direction != 1 && k->direction != -1) BAD("Kawabata direction = %d, expected +1 or -1", k->direction);
    for (int i = 0; i < k->n; ++i) {
        snprintf(what, sizeof what, "Kawabata turning point %d strain", i + 1);
        FINITE(k->eps[i], what);
        snprintf(what, sizeof what, "Kawabata turning point %d tension", i + 1);
        FINITE(k->F[i], what);
    }
    const iwan_memory *w = &d->iwan;
    if (w->direction != 1 && w->direction != -1) BAD("Iwan direction = %d, expected +1 or -1", w->direction);
    FINITE(w->eps_ref, "Iwan reference strain");
    for (int i = 0; i < IWAN_ELEMENTS; ++i) {
        snprintf(what, sizeof what, "Iwan element %d spring strain", i + 1);
        FINITE(w->q[i], what);
    }
    /* past initialisation the parameters have passed the physics' checks; they must again */
    if (s->fmu_state != S_INIT && tether_check(M, msg, len) != 0) return -1;
#undef FINITE
#undef BAD
    return 0;
}

/* CVODE is set up from the structural parameters; after a restore it is rebuilt from the
 * restored model and restarted, and after a save as well, so both continue alike */
static void drop_integrator(instance *c)
{
    integrator_free(c->integrator);
    c->integrator = NULL;
    c->needs_reset = 1;
}

fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate)
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2GetFMUstate", S_SAVED);
    CHECK_NOT_NULL("fmi2GetFMUstate", FMUstate);
    snapshot *s = (snapshot *)*FMUstate;
    if (!s) {
        s = (snapshot *)malloc(sizeof *s);
        if (!s) return fail(c, "fmi2GetFMUstate: out of memory");
    } else if (!snapshot_valid(s)) {
        return fail(c, "fmi2GetFMUstate: *FMUstate is not NULL and not a state of this FMU");
    }
    take_snapshot(c, s);
    *FMUstate = s;
    if (c->type == fmi2CoSimulation && c->integrator) drop_integrator(c);
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate FMUstate)
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2SetFMUstate", S_ANY_BUT_FATAL);
    CHECK_NOT_NULL("fmi2SetFMUstate", FMUstate);
    /* check a scratch copy; the instance is touched only once all of it is good */
    snapshot s;
    memcpy(&s, FMUstate, sizeof s);
    char msg[512];
    if (snapshot_check(&s, msg, sizeof msg) != 0) return refuse(c, "fmi2SetFMUstate: FMUstate is not a state this FMU may restore: %s", msg);
    int state = s.fmu_state;
    if (c->type == fmi2CoSimulation) {
        if (state & (S_INIT | S_EVENT | S_CONTINUOUS)) state = S_STEP_COMPLETE;
    } else if (state & (S_STEP_COMPLETE | S_STEP_FAILED)) {
        state = S_EVENT;
    }
    c->model = s.model;
    if (state != S_INIT) {
        /* derived from the parameters: recomputed, not taken from the bytes */
        c->model.d.rising_limit = elastic_rising_limit(&c->model.p);
        c->model.d.compression_limit = elastic_compression_limit(&c->model.p);
    }
    memcpy(c->y, s.y, sizeof c->y);
    c->time = s.time;
    c->last_successful_time = s.last_successful_time;
    c->start_time = s.start_time;
    c->initialized = state != S_INIT; /* in initialization mode, initialise again from the parameters */
    c->state = state;
    if (c->type == fmi2CoSimulation) drop_integrator(c);
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *FMUstate)
{
    instance *c = as_instance(comp);
    /* allowed in every run state, fatal included: a state that cannot be freed is a leak */
    if (!c) return fmi2Error;
    if (!FMUstate) return fmi2OK;
    free(*FMUstate);
    *FMUstate = NULL;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate FMUstate, size_t *size)
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2SerializedFMUstateSize", S_ANY_BUT_FATAL);
    CHECK_NOT_NULL("fmi2SerializedFMUstateSize", FMUstate);
    CHECK_NOT_NULL("fmi2SerializedFMUstateSize", size);
    *size = sizeof(snapshot);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size)
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2SerializeFMUstate", S_ANY_BUT_FATAL);
    CHECK_NOT_NULL("fmi2SerializeFMUstate", FMUstate);
    CHECK_NOT_NULL("fmi2SerializeFMUstate", serializedState);
    if (size != sizeof(snapshot))
        return fail(c, "fmi2SerializeFMUstate: size = %zu, expected %zu bytes", size, sizeof(snapshot));
    if (!snapshot_valid((const snapshot *)FMUstate)) return fail(c, "fmi2SerializeFMUstate: FMUstate is not a state of this FMU");
    memcpy(serializedState, FMUstate, sizeof(snapshot));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte serializedState[], size_t size, fmi2FMUstate *FMUstate)
{
    instance *c = as_instance(comp);
    CHECK_STATE("fmi2DeSerializeFMUstate", S_ANY_BUT_FATAL);
    CHECK_NOT_NULL("fmi2DeSerializeFMUstate", serializedState);
    CHECK_NOT_NULL("fmi2DeSerializeFMUstate", FMUstate);
    if (size != sizeof(snapshot))
        return fail(c, "fmi2DeSerializeFMUstate: size = %zu, expected %zu bytes of a KevlarTether state", size, sizeof(snapshot));
    snapshot tmp;
    memcpy(&tmp, serializedState, sizeof tmp);
    char msg[512];
    if (snapshot_check(&tmp, msg, sizeof msg) != 0) return refuse(c, "fmi2DeSerializeFMUstate: the bytes are not a state this FMU may restore: %s", msg);
    snapshot *s = (snapshot *)*FMUstate;
    if (s && !snapshot_valid(s)) return fail(c, "fmi2DeSerializeFMUstate: *FMUstate is not NULL and not a state of this FMU");
    if (!s) {
        s = (snapshot *)malloc(sizeof *s);
        if (!s) return fail(c, "fmi2DeSerializeFMUstate: out of memory");
    }
    *s = tmp;
    *FMUstate = s;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    instance *c = as_instance(comp);
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    CHECK_STATE("fmi2GetDirectionalDerivative", S_READABLE);
    return fail(c, "fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative is false)");
}

/* ---- Model Exchange ------------------------------------------------------------------------ */
#define CHECK_ME(function)                                                                         \
    do {                                                                                           \
        if (!c) return fmi2Error;                                                                  \
        if (c->type != fmi2ModelExchange)                                                          \
            return fail(c, "%s: a Model Exchange function called on a Co-Simulation instance", function); \
    } while (0)
#define CHECK_CS(function)                                                                         \
    do {                                                                                           \
        if (!c) return fmi2Error;                                                                  \
        if (c->type != fmi2CoSimulation)                                                           \
            return fail(c, "%s: a Co-Simulation function called on a Model Exchange instance", function); \
    } while (0)

static fmi2Status check_count(instance *c, const char *function, const char *what, size_t n, size_t expected)
{
    if (n != expected) return fail(c, "%s: %s = %zu, expected %zu", function, what, n, expected);
    return fmi2OK;
}

fmi2Status fmi2EnterEventMode(fmi2Component comp)
{
    instance *c = as_instance(comp);
    CHECK_ME("fmi2EnterEventMode");
    CHECK_STATE("fmi2EnterEventMode", S_EVENT | S_CONTINUOUS);
    c->state = S_EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component comp, fmi2EventInfo *info)
{
    instance *c = as_instance(comp);
    CHECK_ME("fmi2NewDiscreteStates");
    CHECK_STATE("fmi2NewDiscreteStates", S_EVENT);
    CHECK_NOT_NULL("fmi2NewDiscreteStates", info);
    char msg[1024];
    const int n = tether_event_update(&c->model, c->time, c->y, msg, sizeof msg);
    if (n > 0) log_event(c, "%s", msg);
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = fmi2False;
    info->nextEventTime = 0.0;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component comp)
{
    instance *c = as_instance(comp);
    CHECK_ME("fmi2EnterContinuousTimeMode");
    CHECK_STATE("fmi2EnterContinuousTimeMode", S_EVENT);
    c->state = S_CONTINUOUS;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component comp, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation)
{
    instance *c = as_instance(comp);
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK_ME("fmi2CompletedIntegratorStep");
    CHECK_STATE("fmi2CompletedIntegratorStep", S_CONTINUOUS);
    CHECK_NOT_NULL("fmi2CompletedIntegratorStep", enterEventMode);
    CHECK_NOT_NULL("fmi2CompletedIntegratorStep", terminateSimulation);
    char msg[512];
    if (tether_check_range(&c->model, c->time, c->y, msg, sizeof msg)) log_warning(c, "%s", msg);
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component comp, fmi2Real time)
{
    instance *c = as_instance(comp);
    CHECK_ME("fmi2SetTime");
    CHECK_STATE("fmi2SetTime", S_EVENT | S_CONTINUOUS);
    if (!isfinite(time)) return fail(c, "fmi2SetTime: time = %g is not finite", time);
    c->time = time;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component comp, const fmi2Real x[], size_t nx)
{
    instance *c = as_instance(comp);
    CHECK_ME("fmi2SetContinuousStates");
    CHECK_STATE("fmi2SetContinuousStates", S_CONTINUOUS);
    CHECK_NOT_NULL("fmi2SetContinuousStates", x);
    if (check_count(c, "fmi2SetContinuousStates", "nx", nx, N_STATES) != fmi2OK) return fmi2Error;
    for (size_t i = 0; i < nx; ++i)
        if (!isfinite(x[i])) return fail(c, "fmi2SetContinuousStates: x[%zu] = %g is not finite", i, x[i]);
    memcpy(c->y, x, sizeof c->y);
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component comp, fmi2Real derivatives[], size_t nx)
{
    instance *c = as_instance(comp);
    CHECK_ME("fmi2GetDerivatives");
    CHECK_STATE("fmi2GetDerivatives", S_INIT | S_EVENT | S_CONTINUOUS | S_TERMINATED | S_ERROR);
    CHECK_NOT_NULL("fmi2GetDerivatives", derivatives);
    if (check_count(c, "fmi2GetDerivatives", "nx", nx, N_STATES) != fmi2OK) return fmi2Error;
    if (ensure_initialized(c, "fmi2GetDerivatives") != fmi2OK) return fmi2Error;
    tether_derivatives(&c->model, c->time, c->y, derivatives);
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component comp, fmi2Real eventIndicators[], size_t ni)
{
    instance *c = as_instance(comp);
    CHECK_ME("fmi2GetEventIndicators");
    CHECK_STATE("fmi2GetEventIndicators", S_INIT | S_EVENT | S_CONTINUOUS | S_TERMINATED | S_ERROR);
    CHECK_NOT_NULL("fmi2GetEventIndicators", eventIndicators);
    if (check_count(c, "fmi2GetEventIndicators", "ni", ni, N_EVENTS) != fmi2OK) return fmi2Error;
    if (ensure_initialized(c, "fmi2GetEventIndicators") != fmi2OK) return fmi2Error;
    tether_event_indicators(&c->model, c->time, c->y, eventIndicators);
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component comp, fmi2Real x[], size_t nx)
{
    instance *c = as_instance(comp);
    CHECK_ME("fmi2GetContinuousStates");
    CHECK_STATE("fmi2GetContinuousStates", S_INIT | S_EVENT | S_CONTINUOUS | S_TERMINATED | S_ERROR);
    CHECK_NOT_NULL("fmi2GetContinuousStates", x);
    if (check_count(c, "fmi2GetContinuousStates", "nx", nx, N_STATES) != fmi2OK) return fmi2Error;
    if (ensure_initialized(c, "fmi2GetContinuousStates") != fmi2OK) return fmi2Error;
    memcpy(x, c->y, sizeof c->y);
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component comp, fmi2Real x_nominal[], size_t nx)
{
    instance *c = as_instance(comp);
    CHECK_ME("fmi2GetNominalsOfContinuousStates");
    CHECK_STATE("fmi2GetNominalsOfContinuousStates", S_INSTANTIATED | S_INIT | S_EVENT | S_CONTINUOUS | S_TERMINATED | S_ERROR);
    CHECK_NOT_NULL("fmi2GetNominalsOfContinuousStates", x_nominal);
    if (check_count(c, "fmi2GetNominalsOfContinuousStates", "nx", nx, N_STATES) != fmi2OK) return fmi2Error;
    tether_nominals(&c->model, x_nominal);
    return fmi2OK;
}

/* ---- Co-Simulation ------------------------------------------------------------------------- */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    instance *c = as_instance(comp);
    CHECK_CS("fmi2SetRealInputDerivatives");
    CHECK_STATE("fmi2SetRealInputDerivatives", S_INSTANTIATED | S_INIT | S_STEP_COMPLETE);
    if (nvr == 0) return fmi2OK;
    CHECK_NOT_NULL("fmi2SetRealInputDerivatives", vr);
    CHECK_NOT_NULL("fmi2SetRealInputDerivatives", order);
    CHECK_NOT_NULL("fmi2SetRealInputDerivatives", value);
    for (size_t i = 0; i < nvr; ++i) {
        const char *name = real_name(vr[i]);
        if (!name) return fail(c, "fmi2SetRealInputDerivatives: no Real variable has value reference %u", (unsigned)vr[i]);
        if (order[i] < 1 || order[i] > TETHER_INPUT_DERIVATIVE_ORDER)
            return fail(c, "fmi2SetRealInputDerivatives: order = %d for '%s'; expected 1..%d", (int)order[i], name, TETHER_INPUT_DERIVATIVE_ORDER);
        if (!isfinite(value[i])) return fail(c, "fmi2SetRealInputDerivatives: d%s/dt = %g is not finite", name, value[i]);
        double *target = NULL;
        if (strcmp(name, "force") == 0) target = &c->model.in.force_der[order[i] - 1];
        else if (strcmp(name, "load") == 0) target = &c->model.in.load_der[order[i] - 1];
        else return fail(c, "fmi2SetRealInputDerivatives: '%s' takes no derivative (only the inputs force and load are interpolated)", name);
        if (*target != value[i]) { *target = value[i]; c->needs_reset = 1; }
        c->model.in.t_ref = c->time;
    }
    return fmi2OK;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    instance *c = as_instance(comp);
    (void)vr; (void)order; (void)value;
    CHECK_CS("fmi2GetRealOutputDerivatives");
    CHECK_STATE("fmi2GetRealOutputDerivatives", S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED | S_ERROR);
    if (nvr == 0) return fmi2OK;
    return fail(c, "fmi2GetRealOutputDerivatives: not provided (maxOutputDerivativeOrder is 0)");
}

fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    instance *c = as_instance(comp);
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK_CS("fmi2DoStep");
    CHECK_STATE("fmi2DoStep", S_STEP_COMPLETE);
    if (!(communicationStepSize > 0.0) || !isfinite(communicationStepSize))
        return fail(c, "fmi2DoStep: communicationStepSize = %g s, expected a positive step", communicationStepSize);
    const double tol = 1e-9 * (1.0 + fabs(c->time));
    if (!isfinite(currentCommunicationPoint) || fabs(currentCommunicationPoint - c->time) > tol)
        return fail(c, "fmi2DoStep: currentCommunicationPoint = %.17g s, but the FMU is at %.17g s",
                    currentCommunicationPoint, c->time);
    char msg[1024];
    if (!c->integrator) {
        c->integrator = integrator_create(&c->model, integrator_log, c, msg, sizeof msg);
        if (!c->integrator) return fail(c, "fmi2DoStep: %s", msg);
        c->needs_reset = 1;
    }
    if (c->needs_reset) {
        /* inputs changed (or a state was restored): switch what the new inputs switch, restart */
        const int n = tether_event_update(&c->model, c->time, c->y, msg, sizeof msg);
        if (n > 0) log_event(c, "%s", msg);
        if (integrator_reset(c->integrator, c->time, c->y) != 0)
            return fail(c, "fmi2DoStep: could not restart CVODE at t = %.17g s: %s", c->time, integrator_error(c->integrator));
        c->needs_reset = 0;
    }
    const double t_end = currentCommunicationPoint + communicationStepSize;
    double t_reached = c->time;
    const int rc = integrator_advance(c->integrator, t_end, &t_reached, c->y);
    c->time = t_reached;
    if (rc != 0) {
        c->last_successful_time = t_reached;
        c->state = S_STEP_FAILED;
        c->needs_reset = 1;
        log_discard(c, "fmi2DoStep: the step from %.17g s to %.17g s stopped at %.17g s: %s",
                    currentCommunicationPoint, t_end, t_reached, integrator_error(c->integrator));
        return fmi2Discard;
    }
    c->time = t_end;
    c->last_successful_time = t_end;
    if (tether_check_range(&c->model, c->time, c->y, msg, sizeof msg)) log_warning(c, "%s", msg);
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component comp)
{
    instance *c = as_instance(comp);
    CHECK_CS("fmi2CancelStep");
    return fail(c, "fmi2CancelStep: steps are synchronous (canRunAsynchronuously is false); there is nothing to cancel");
}

static fmi2Status status_kind_error(instance *c, const char *function, int kind)
{
    return fail(c, "%s: status kind %d is not provided", function, kind);
}

fmi2Status fmi2GetStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Status *value)
{
    instance *c = as_instance(comp);
    CHECK_CS("fmi2GetStatus");
    CHECK_STATE("fmi2GetStatus", S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED);
    CHECK_NOT_NULL("fmi2GetStatus", value);
    if (s == fmi2DoStepStatus) {
        *value = c->state == S_STEP_FAILED ? fmi2Discard : fmi2OK;
        return fmi2OK;
    }
    return status_kind_error(c, "fmi2GetStatus", (int)s);
}

fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value)
{
    instance *c = as_instance(comp);
    CHECK_CS("fmi2GetRealStatus");
    CHECK_STATE("fmi2GetRealStatus", S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED);
    CHECK_NOT_NULL("fmi2GetRealStatus", value);
    if (s == fmi2LastSuccessfulTime) {
        *value = c->last_successful_time;
        return fmi2OK;
    }
    return status_kind_error(c, "fmi2GetRealStatus", (int)s);
}

fmi2Status fmi2GetIntegerStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Integer *value)
{
    instance *c = as_instance(comp);
    (void)value;
    CHECK_CS("fmi2GetIntegerStatus");
    CHECK_STATE("fmi2GetIntegerStatus", S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED);
    return status_kind_error(c, "fmi2GetIntegerStatus", (int)s);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Boolean *value)
{
    instance *c = as_instance(comp);
    CHECK_CS("fmi2GetBooleanStatus");
    CHECK_STATE("fmi2GetBooleanStatus", S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED);
    CHECK_NOT_NULL("fmi2GetBooleanStatus", value);
    if (s == fmi2Terminated) {
        *value = fmi2False;
        return fmi2OK;
    }
    return status_kind_error(c, "fmi2GetBooleanStatus", (int)s);
}

fmi2Status fmi2GetStringStatus(fmi2Component comp, const fmi2StatusKind s, fmi2String *value)
{
    instance *c = as_instance(comp);
    (void)value;
    CHECK_CS("fmi2GetStringStatus");
    CHECK_STATE("fmi2GetStringStatus", S_STEP_COMPLETE | S_STEP_FAILED | S_TERMINATED);
    return status_kind_error(c, "fmi2GetStringStatus", (int)s);
}
