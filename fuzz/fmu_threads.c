/* fmu_threads: several FMU instances simulated at once in threads (built with ThreadSanitizer by
 * fuzz/build_fuzz.py --sanitize thread --driver fmu_threads.c), their results compared bit for bit
 * with the same runs made one after the other.
 *
 *   fmu_threads [THREADS]      (default 8)
 *
 * Each run is a Co-Simulation of one of several models (Kawabata payload under a steady force,
 * Bouc-Wen payload, Iwan element, creep under load, cubic with slack), with a state saved,
 * serialized, restored half-way and logging on, so that every part of an instance is exercised.
 * Exit 0 and "bit-identical" when every threaded run equals its serial twin.
 */
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "model_variables.h"

#define STEPS 400
#define OUTPUTS 3

#define VR_OF(v, id, name, ...) if (strcmp(wanted, name) == 0) return v;
static fmi2ValueReference vr_of(const char *wanted)
{
    KT_REAL_VARIABLES(VR_OF)
    KT_INTEGER_VARIABLES(VR_OF)
    KT_BOOLEAN_VARIABLES(VR_OF)
    fprintf(stderr, "fmu_threads: no variable %s\n", wanted);
    exit(2);
}

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...)
{
    char buf[2048];
    va_list ap;
    va_start(ap, message);
    vsnprintf(buf, sizeof buf, message, ap);
    va_end(ap);
    *(unsigned long *)env += strlen(buf) + strlen(name) + strlen(category) + (unsigned)status;
}

typedef struct {
    int model;
    double out[STEPS][OUTPUTS];
    unsigned long logged;
    int failed;
} run;

static void set_int(fmi2Component c, const char *name, int v)
{
    const fmi2ValueReference r = vr_of(name);
    fmi2SetInteger(c, &r, 1, &v);
}
static void set_bool(fmi2Component c, const char *name, int v)
{
    const fmi2ValueReference r = vr_of(name);
    const fmi2Boolean b = v ? fmi2True : fmi2False;
    fmi2SetBoolean(c, &r, 1, &b);
}
static void set_real(fmi2Component c, const char *name, double v)
{
    const fmi2ValueReference r = vr_of(name);
    fmi2SetReal(c, &r, 1, &v);
}

static void *simulate(void *arg)
{
    run *R = (run *)arg;
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, &R->logged};
    char name[32];
    snprintf(name, sizeof name, "run%d", R->model);
    fmi2Component c = fmi2Instantiate(name, fmi2CoSimulation, KT_MODEL_GUID, NULL, &cb, fmi2False, fmi2True);
    if (!c) { R->failed = 1; return NULL; }
    fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
    double h = 0.005;
    switch (R->model % 5) {
    case 0: /* Kawabata payload under a steady force (issue 27, F5) */
        set_int(c, "rig", 2); set_int(c, "damping", 2); set_int(c, "hysteresis", 2); set_bool(c, "slack", 1);
        set_real(c, "force", 100.0);
        break;
    case 1: /* Bouc-Wen payload released from a displacement */
        set_int(c, "rig", 2); set_int(c, "stiffness", 2); set_int(c, "hysteresis", 3); set_real(c, "x0", 0.05);
        break;
    case 2: /* Iwan element, driven below */
        set_int(c, "rig", 1); set_int(c, "hysteresis", 4); set_real(c, "iw_k1", 2e4); set_real(c, "iw_eps1", 1e-3);
        break;
    case 3: /* creep under a load */
        set_int(c, "rig", 3); set_bool(c, "creep", 1); set_real(c, "load", 60.0); h = 50.0;
        break;
    default: /* cubic with slack, released far up */
        set_int(c, "rig", 2); set_int(c, "stiffness", 2); set_bool(c, "slack", 1); set_real(c, "x0", -0.5);
        break;
    }
    if (fmi2EnterInitializationMode(c) != fmi2OK || fmi2ExitInitializationMode(c) != fmi2OK) R->failed = 1;
    const fmi2ValueReference out[OUTPUTS] = {vr_of("tension"), vr_of("strain"), vr_of("elongation")};
    double t = 0.0;
    for (int k = 0; k < STEPS && !R->failed; ++k) {
        if (R->model % 5 == 2) {
            const double u = 0.2 * (k % 50 < 25 ? k % 50 : 50 - k % 50) / 25.0;
            set_real(c, "elongation", u);
            set_real(c, "elongation_rate", k % 50 < 25 ? 0.2 / (25 * h) : -0.2 / (25 * h));
        }
        if (k == STEPS / 2) {
            /* save, serialize, restore through the bytes */
            fmi2FMUstate s = NULL, s2 = NULL;
            size_t size = 0;
            if (fmi2GetFMUstate(c, &s) != fmi2OK || fmi2SerializedFMUstateSize(c, s, &size) != fmi2OK) R->failed = 1;
            fmi2Byte *bytes = (fmi2Byte *)malloc(size ? size : 1);
            if (!R->failed && (fmi2SerializeFMUstate(c, s, bytes, size) != fmi2OK ||
                               fmi2DeSerializeFMUstate(c, bytes, size, &s2) != fmi2OK || fmi2SetFMUstate(c, s2) != fmi2OK))
                R->failed = 1;
            free(bytes);
            fmi2FreeFMUstate(c, &s);
            fmi2FreeFMUstate(c, &s2);
        }
        if (fmi2DoStep(c, t, h, fmi2True) != fmi2OK) R->failed = 1;
        t += h;
        fmi2GetReal(c, out, OUTPUTS, R->out[k]);
    }
    fmi2FreeInstance(c);
    return NULL;
}

int main(int argc, char **argv)
{
    const int n = argc > 1 ? atoi(argv[1]) : 8;
    if (n < 1 || n > 64) { fprintf(stderr, "usage: fmu_threads [THREADS 1..64]\n"); return 2; }
    run *serial = (run *)calloc((size_t)n, sizeof *serial), *threaded = (run *)calloc((size_t)n, sizeof *threaded);
    pthread_t *th = (pthread_t *)calloc((size_t)n, sizeof *th);
    if (!serial || !threaded || !th) return 2;
    for (int i = 0; i < n; ++i) {
        serial[i].model = threaded[i].model = i;
        simulate(&serial[i]);
    }
    for (int i = 0; i < n; ++i)
        if (pthread_create(&th[i], NULL, simulate, &threaded[i]) != 0) { fprintf(stderr, "fmu_threads: pthread_create failed\n"); return 2; }
    for (int i = 0; i < n; ++i) pthread_join(th[i], NULL);
    int bad = 0;
    for (int i = 0; i < n; ++i) {
        if (serial[i].failed || threaded[i].failed) {
            printf("fmu_threads: run %d failed (serial %d, threaded %d)\n", i, serial[i].failed, threaded[i].failed);
            bad = 1;
        } else if (memcmp(serial[i].out, threaded[i].out, sizeof serial[i].out) != 0 || serial[i].logged != threaded[i].logged) {
            printf("fmu_threads: run %d differs between serial and threaded\n", i);
            bad = 1;
        }
    }
    if (!bad) printf("fmu_threads: %d instances in %d threads, %d steps each: bit-identical to serial\n", n, n, STEPS);
    free(serial);
    free(threaded);
    free(th);
    return bad;
}
