/* fmu_fuzz: random FMI 2.0 call sequences against the KevlarTether FMU, linked in from the FMU's
 * own sources/ (fuzz/build_fuzz.py builds it with -fsanitize=address,undefined).
 *
 *   fmu_fuzz SEED COUNT [FIRST]   run sequences FIRST .. FIRST+COUNT-1 of campaign SEED
 *
 * Each sequence instantiates one or two instances (Model Exchange or Co-Simulation, sometimes with
 * hostile arguments) and makes random calls of every fmi2 function, in and out of order, with
 * hostile values (NaN, inf, huge, negative, NULL pointers, wrong value references, wrong sizes),
 * on its own instances, on NULL and on a foreign pointer. FMU states are taken, serialized,
 * mutated (bit flips, truncation, fields overwritten with hostile values) and restored. Sequence i
 * of a campaign depends on (SEED, i) only, so a finding is replayed with COUNT = 1, FIRST = i.
 *
 * The sanitizers abort on the first report; the death callback names the sequence. Exit 0 and the
 * line "fmu_fuzz: N sequences, M calls" when all ran.
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

/* ---- random numbers (splitmix64: a sequence depends on its seed alone) ---------------------- */
static uint64_t rng_state;
static uint64_t next_u64(void)
{
    uint64_t z = (rng_state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}
static unsigned below(unsigned n) { return n ? (unsigned)(next_u64() % n) : 0u; }
static int chance(unsigned percent) { return below(100) < percent; }
static double uniform(void) { return (double)(next_u64() >> 11) / 9007199254740992.0; }

/* ---- the variables of the FMU, from its generated table ------------------------------------- */
typedef struct { unsigned vr; double start, lo, hi; } real_var;
#define ONE_REAL(v, id, name, kind, var, hs, st, lo, hi) {v, st, lo, hi},
static const real_var reals[] = {KT_REAL_VARIABLES(ONE_REAL)};
typedef struct { unsigned vr; int start, lo, hi; } int_var;
#define ONE_INT(v, id, name, kind, var, st, lo, hi) {v, st, lo, hi},
static const int_var ints[] = {KT_INTEGER_VARIABLES(ONE_INT)};
#define ONE_BOOL(v, id, name, kind, var, st) v,
static const unsigned bools[] = {KT_BOOLEAN_VARIABLES(ONE_BOOL)};
#define ONE_BOOL_PARAM(v, id, name, kind, var, st) (kind == KT_PARAM ? (long)v : -1L),
static const long bool_params[] = {KT_BOOLEAN_VARIABLES(ONE_BOOL_PARAM)}; /* -1: not a parameter */
#define N_REALS (sizeof reals / sizeof reals[0])
#define N_INTS (sizeof ints / sizeof ints[0])
#define N_BOOLS (sizeof bools / sizeof bools[0])

static double hostile_double(void)
{
    static const double pool[] = {0.0, -0.0, 1.0, -1.0, 1e-300, -1e-300, 4.9e-324, 1e300, -1e300,
                                  DBL_MAX, -DBL_MAX, HUGE_VAL, -HUGE_VAL, 1e-9, 1e6, -1e6, 0.5, 2.0};
    switch (below(6)) {
    case 0: return NAN;
    case 1: return pool[below(sizeof pool / sizeof pool[0])];
    case 2: return (uniform() - 0.5) * pow(10.0, (double)below(40) - 20.0);
    default: {
        const real_var *r = &reals[below(N_REALS)];
        const double s = r->start != 0.0 ? r->start : 1.0;
        return s * (0.5 + uniform());
    }
    }
}

/* a value inside the variable's range, near its start value */
static double plausible_real(unsigned vr)
{
    for (size_t i = 0; i < N_REALS; ++i) {
        if (reals[i].vr != vr) continue;
        double v = (reals[i].start != 0.0 ? reals[i].start : 1e-3) * (0.8 + 0.4 * uniform());
        if (v < reals[i].lo) v = reals[i].lo;
        if (v > reals[i].hi) v = reals[i].hi;
        return v;
    }
    return uniform();
}

static unsigned hostile_vr(void)
{
    switch (below(10)) {
    case 0: return 0xffffffffu;
    case 1: return below(1000);
    case 2: return ints[below(N_INTS)].vr;
    case 3: return bools[below(N_BOOLS)];
    default: return reals[below(N_REALS)].vr;
    }
}

/* ---- the logger: formats every message, as an importer would -------------------------------- */
static unsigned long logged;
static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...)
{
    char buf[4096];
    va_list ap;
    (void)env;
    va_start(ap, message);
    vsnprintf(buf, sizeof buf, message, ap);
    va_end(ap);
    logged += strlen(buf) + strlen(name ? name : "") + strlen(category ? category : "") + (unsigned)status;
}

/* ---- one sequence ---------------------------------------------------------------------------- */
#define MAX_STATES 4
#define MAX_N 8
typedef struct {
    fmi2Component c;
    fmi2Type type;
    fmi2FMUstate states[MAX_STATES];
} slot;

static unsigned long calls, steps_ok, restores_ok, deserialized_ok;
static long current_sequence = -1;
static uint64_t campaign_seed;

/* a component argument: mostly our instance, sometimes NULL or a foreign pointer */
static fmi2Component pick_component(slot *s, void *foreign)
{
    const unsigned r = below(40);
    if (r == 0) return NULL;
    if (r == 1) return foreign;
    return s->c;
}

static size_t pick_n(void)
{
    const unsigned r = below(20);
    if (r == 0) return 0;
    if (r == 1) return MAX_N; /* the most the arrays hold */
    return 1 + below(MAX_N);
}

static void fill_vrs(fmi2ValueReference *vr, size_t n, int kind)
{
    for (size_t i = 0; i < n; ++i) {
        if (chance(5)) { vr[i] = hostile_vr(); continue; }
        if (kind == 0) vr[i] = reals[below(N_REALS)].vr;
        else if (kind == 1) vr[i] = ints[below(N_INTS)].vr;
        else vr[i] = bools[below(N_BOOLS)];
    }
}

/* mutate serialized bytes: bit flips, a field overwritten with a hostile value, or a garbage block */
static void mutate(unsigned char *b, size_t size)
{
    const int rounds = 1 + (int)below(4);
    for (int k = 0; k < rounds && size > 0; ++k) {
        switch (below(5)) {
        case 0: b[below((unsigned)size)] ^= (unsigned char)(1u << below(8)); break;
        case 1:
            if (size >= 8) {
                const double v = hostile_double();
                memcpy(b + 8 * below((unsigned)(size / 8)), &v, 8);
            }
            break;
        case 2:
            if (size >= 4) {
                static const int32_t pool[] = {0, -1, 1, 2, 3, 4, 5, 64, 65, 256, 1000000, INT32_MIN, INT32_MAX};
                const int32_t v = pool[below(sizeof pool / sizeof pool[0])];
                memcpy(b + 4 * below((unsigned)(size / 4)), &v, 4);
            }
            break;
        case 3: {
            const size_t at = below((unsigned)size), len = 1 + below(32);
            for (size_t i = at; i < size && i < at + len; ++i) b[i] = (unsigned char)next_u64();
            break;
        }
        default: {
            const uint64_t v = next_u64();
            if (size >= 8) memcpy(b + 8 * below((unsigned)(size / 8)), &v, 8);
            break;
        }
        }
    }
}

static void state_call(slot *s, fmi2Component c)
{
    fmi2FMUstate *st = &s->states[below(MAX_STATES)];
    switch (below(7)) {
    case 0: fmi2GetFMUstate(c, chance(5) ? NULL : st); break;
    case 1: if ((*st || chance(5)) && fmi2SetFMUstate(c, *st) == fmi2OK) ++restores_ok; break;
    case 2: if (*st && fmi2FreeFMUstate(c, st) == fmi2OK) *st = NULL; break; /* a foreign c frees nothing */
    default: {
        /* serialize, mutate (or not), deserialize, restore */
        if (!*st) { fmi2GetFMUstate(c, st); if (!*st) return; }
        size_t size = 0;
        if (fmi2SerializedFMUstateSize(c, *st, &size) != fmi2OK || size == 0 || size > 1 << 20) return;
        unsigned char *buf = (unsigned char *)malloc(size);
        if (!buf) return;
        memset(buf, 0, size);
        fmi2SerializeFMUstate(c, *st, (fmi2Byte *)buf, chance(5) ? size - 1 : size);
        size_t use = size;
        if (chance(70)) mutate(buf, size);
        if (chance(10)) use = below((unsigned)size); /* truncated */
        fmi2FMUstate *dst = &s->states[below(MAX_STATES)];
        if (fmi2DeSerializeFMUstate(c, (const fmi2Byte *)buf, use, chance(3) ? NULL : dst) == fmi2OK) ++deserialized_ok;
        free(buf);
        if (*dst && chance(80) && fmi2SetFMUstate(c, *dst) == fmi2OK) ++restores_ok;
        break;
    }
    }
}

static void one_call(slot *s, void *foreign)
{
    fmi2Component c = pick_component(s, foreign);
    fmi2ValueReference vr[MAX_N];
    fmi2Real rv[MAX_N];
    fmi2Integer iv[MAX_N];
    fmi2Boolean bv[MAX_N];
    fmi2String sv[MAX_N];
    const size_t n = pick_n();
    const int null_arrays = chance(4);
    for (size_t i = 0; i < MAX_N; ++i) { rv[i] = 0.0; iv[i] = 0; bv[i] = 0; sv[i] = "x"; }
    ++calls;
    switch (below(44)) {
    case 0: fmi2SetupExperiment(c, chance(50), chance(50) ? 1e-6 : hostile_double(), chance(70) ? 0.0 : hostile_double(),
                                chance(50), chance(50) ? 10.0 : hostile_double()); break;
    case 1: case 2: fmi2EnterInitializationMode(c); break;
    case 3: case 4: fmi2ExitInitializationMode(c); break;
    case 5: fmi2Terminate(c); break;
    case 6: if (chance(30)) fmi2Reset(c); break;
    case 7: case 8: case 9: {
        fill_vrs(vr, n, 0);
        for (size_t i = 0; i < n; ++i) {
            rv[i] = chance(80) ? plausible_real(vr[i]) : hostile_double();
        }
        fmi2SetReal(c, null_arrays ? NULL : vr, n, chance(3) ? NULL : rv);
        break;
    }
    case 10: case 11: {
        fill_vrs(vr, n, 1);
        for (size_t i = 0; i < n; ++i) {
            const int_var *v = &ints[below(N_INTS)];
            iv[i] = chance(70) ? v->lo + (int)below((unsigned)(v->hi - v->lo + 1)) : (int)next_u64();
        }
        fmi2SetInteger(c, null_arrays ? NULL : vr, n, chance(3) ? NULL : iv);
        break;
    }
    case 12: {
        fill_vrs(vr, n, 2);
        for (size_t i = 0; i < n; ++i) bv[i] = chance(80) ? (fmi2Boolean)below(2) : (fmi2Boolean)next_u64();
        fmi2SetBoolean(c, null_arrays ? NULL : vr, n, chance(3) ? NULL : bv);
        break;
    }
    case 13: fill_vrs(vr, n, 0); fmi2SetString(c, null_arrays ? NULL : vr, n, chance(20) ? NULL : sv); break;
    case 14: case 15: fill_vrs(vr, n, 0); fmi2GetReal(c, null_arrays ? NULL : vr, n, chance(3) ? NULL : rv); break;
    case 16: fill_vrs(vr, n, 1); fmi2GetInteger(c, null_arrays ? NULL : vr, n, chance(3) ? NULL : iv); break;
    case 17: fill_vrs(vr, n, 2); fmi2GetBoolean(c, null_arrays ? NULL : vr, n, chance(3) ? NULL : bv); break;
    case 18: fill_vrs(vr, n, 0); fmi2GetString(c, null_arrays ? NULL : vr, n, chance(3) ? NULL : sv); break;
    case 19: {
        const char *cats[] = {"logEvents", "logAll", "nonsense", NULL, "logStatusError"};
        fmi2String list[MAX_N];
        for (size_t i = 0; i < n; ++i) list[i] = cats[below(5)];
        fmi2SetDebugLogging(c, (fmi2Boolean)below(2), n, chance(5) ? NULL : list);
        break;
    }
    case 20: case 21: case 22: case 23: {
        /* mostly small steps from where the instance is: the campaign explores calls, not long runs */
        double t = 0.0;
        if (s->c && fmi2GetRealStatus(s->c, fmi2LastSuccessfulTime, &t) != fmi2OK) t = 0.0;
        const double h = chance(85) ? pow(10.0, -(double)(1 + below(4))) : hostile_double();
        if (fmi2DoStep(c, chance(85) ? t : hostile_double(), h > 1.0 && isfinite(h) ? 1.0 : h, (fmi2Boolean)below(2)) == fmi2OK)
            ++steps_ok;
        break;
    }
    case 24: fmi2CancelStep(c); break;
    case 25: {
        fmi2Status st;
        fmi2Real r;
        fmi2Integer i;
        fmi2Boolean b;
        fmi2String str;
        const fmi2StatusKind k = (fmi2StatusKind)(chance(80) ? below(4) : (unsigned)next_u64());
        switch (below(5)) {
        case 0: fmi2GetStatus(c, k, chance(5) ? NULL : &st); break;
        case 1: fmi2GetRealStatus(c, k, chance(5) ? NULL : &r); break;
        case 2: fmi2GetIntegerStatus(c, k, chance(5) ? NULL : &i); break;
        case 3: fmi2GetBooleanStatus(c, k, chance(5) ? NULL : &b); break;
        default: fmi2GetStringStatus(c, k, chance(5) ? NULL : &str); break;
        }
        break;
    }
    case 26: {
        fill_vrs(vr, n, 0);
        for (size_t i = 0; i < n; ++i) { iv[i] = chance(80) ? 1 + (int)below(3) : (int)next_u64(); rv[i] = hostile_double(); }
        fmi2SetRealInputDerivatives(c, null_arrays ? NULL : vr, n, chance(3) ? NULL : iv, chance(3) ? NULL : rv);
        break;
    }
    case 27: fill_vrs(vr, n, 0); for (size_t i = 0; i < n; ++i) iv[i] = (int)below(3);
        fmi2GetRealOutputDerivatives(c, null_arrays ? NULL : vr, n, chance(3) ? NULL : iv, chance(3) ? NULL : rv); break;
    case 28: fill_vrs(vr, n, 0); fmi2GetDirectionalDerivative(c, vr, n, vr, n, rv, rv); break;
    /* Model Exchange */
    case 29: fmi2EnterEventMode(c); break;
    case 30: {
        fmi2EventInfo info;
        fmi2NewDiscreteStates(c, chance(5) ? NULL : &info);
        break;
    }
    case 31: fmi2EnterContinuousTimeMode(c); break;
    case 32: {
        fmi2Boolean e, t;
        fmi2CompletedIntegratorStep(c, (fmi2Boolean)below(2), chance(5) ? NULL : &e, chance(5) ? NULL : &t);
        break;
    }
    case 33: fmi2SetTime(c, chance(70) ? uniform() : hostile_double()); break;
    case 34: {
        fmi2Real x[16];
        for (int i = 0; i < 16; ++i) x[i] = chance(80) ? 1e-3 * (uniform() - 0.5) : hostile_double();
        fmi2SetContinuousStates(c, chance(3) ? NULL : x, chance(80) ? KT_NUMBER_OF_STATES : below(16));
        break;
    }
    case 35: case 36: {
        fmi2Real x[16];
        const size_t nx = chance(80) ? KT_NUMBER_OF_STATES : below(16);
        switch (below(4)) {
        case 0: fmi2GetDerivatives(c, chance(3) ? NULL : x, nx); break;
        case 1: fmi2GetEventIndicators(c, chance(3) ? NULL : x, chance(80) ? KT_NUMBER_OF_EVENT_INDICATORS : below(16)); break;
        case 2: fmi2GetContinuousStates(c, chance(3) ? NULL : x, nx); break;
        default: fmi2GetNominalsOfContinuousStates(c, chance(3) ? NULL : x, nx); break;
        }
        break;
    }
    case 37: (void)fmi2GetTypesPlatform(); (void)fmi2GetVersion(); break;
    default: state_call(s, c); break;
    }
}

static void good_start(slot *sl);

static void run_sequence(long index, void *foreign)
{
    rng_state = campaign_seed * 0x2545f4914f6cdd1dull + (uint64_t)index * 0x9e3779b97f4a7c15ull;
    (void)next_u64();
    fmi2CallbackFunctions functions = {logger, calloc, free, NULL, NULL};
    slot s;
    memset(&s, 0, sizeof s);
    s.type = chance(50) ? fmi2ModelExchange : fmi2CoSimulation;
    if (chance(3)) {
        /* hostile instantiation: every one of these must return NULL */
        const char *guids[] = {NULL, "", "{00000000-0000-0000-0000-000000000000}", KT_MODEL_GUID};
        const fmi2Type types[] = {fmi2ModelExchange, fmi2CoSimulation, (fmi2Type)7, (fmi2Type)-1};
        const char *names[] = {NULL, "", "fuzz %s %n", "x"};
        fmi2Component c = fmi2Instantiate(names[below(4)], types[below(4)], guids[below(4)], NULL,
                                          chance(50) ? NULL : &functions, (fmi2Boolean)below(2), (fmi2Boolean)below(2));
        if (c) fmi2FreeInstance(c);
    }
    s.c = fmi2Instantiate(chance(10) ? "%s%s%n%x" : "fuzz", s.type, KT_MODEL_GUID, NULL,
                          chance(10) ? NULL : &functions, fmi2False, (fmi2Boolean)below(2));
    if (!s.c) return;
    if (chance(90)) good_start(&s);
    const int n_calls = 5 + (int)below(40);
    for (int k = 0; k < n_calls; ++k) {
        /* now and then a reset and a good start again, so that errors do not end the exploration */
        if (chance(20) && fmi2Reset(s.c) == fmi2OK) good_start(&s);
        one_call(&s, foreign);
    }
    for (int i = 0; i < MAX_STATES; ++i)
        if (s.states[i]) fmi2FreeFMUstate(s.c, &s.states[i]);
    fmi2FreeInstance(s.c);
    if (chance(5)) fmi2FreeInstance(NULL);
}

/* a good start, so that the calls reach the later states */
static void good_start(slot *s)
{
    fmi2ValueReference vr[MAX_N];
    fmi2Integer iv[MAX_N];
    fmi2Boolean bv[MAX_N];
    size_t n = 0;
    for (size_t i = 0; i < N_INTS && n < MAX_N; ++i, ++n) {
        vr[n] = ints[i].vr;
        iv[n] = ints[i].lo + (int)below((unsigned)(ints[i].hi - ints[i].lo + 1));
    }
    fmi2SetInteger(s->c, vr, n, iv);
    n = 0;
    for (size_t i = 0; i < N_BOOLS && n < MAX_N; ++i) {
        if (bool_params[i] < 0) continue;
        vr[n] = (fmi2ValueReference)bool_params[i];
        bv[n++] = (fmi2Boolean)below(2);
    }
    fmi2SetBoolean(s->c, vr, n, bv);
    fmi2SetupExperiment(s->c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
    fmi2EnterInitializationMode(s->c);
    if (chance(80)) fmi2ExitInitializationMode(s->c);
    if (s->type == fmi2ModelExchange && chance(50)) fmi2EnterContinuousTimeMode(s->c);
}

/* the death callback comes with the sanitizer runtimes (ASan, TSan); a plain build goes without */
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#include <sanitizer/common_interface_defs.h>
#define HAVE_SANITIZER_DEATH_CALLBACK 1
#endif

static void on_death(void)
{
    fprintf(stderr, "fmu_fuzz: FINDING in sequence %ld of campaign seed %llu (replay: fmu_fuzz %llu 1 %ld)\n",
            current_sequence, (unsigned long long)campaign_seed, (unsigned long long)campaign_seed, current_sequence);
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: fmu_fuzz SEED COUNT [FIRST]\n");
        return 2;
    }
    campaign_seed = strtoull(argv[1], NULL, 10);
    const long count = strtol(argv[2], NULL, 10), first = argc > 3 ? strtol(argv[3], NULL, 10) : 0;
#ifdef HAVE_SANITIZER_DEATH_CALLBACK
    __sanitizer_set_death_callback(on_death);
#endif
    /* a foreign component: memory that is not an instance of this FMU (its first bytes are not
     * the instance tag) */
    static unsigned char foreign[4096];
    for (size_t i = 0; i < sizeof foreign; ++i) foreign[i] = (unsigned char)(i * 37u + 11u);
    for (long i = first; i < first + count; ++i) {
        current_sequence = i;
        run_sequence(i, foreign);
    }
    printf("fmu_fuzz: %ld sequences, %lu calls, %lu steps OK, %lu states deserialized and %lu restored "
           "(seed %llu, first %ld)\n", count, calls, steps_ok, deserialized_ok, restores_ok,
           (unsigned long long)campaign_seed, first);
    return 0;
}
