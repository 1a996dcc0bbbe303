// Batch simulation of one experiment with the FMU's physics, mirroring its co-simulation step
// by step (fmu_src/fmi2/fmu.c: fmi2ExitInitializationMode, fmi2SetReal/fmi2SetRealInputDerivatives
// on the inputs, fmi2DoStep), so that a trajectory agrees with the FMU's to round-off.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <time.h>

#include "identify/engine.hpp"

extern "C" {
#include "model_variables.h"
#include "solver/integrator.h"
}

namespace kt {

// ---- name -> field table, generated from modelDescription.xml's variable list -------------------
// The identifiers of the X-macros are the field names of tether_params / tether_inputs /
// tether_outputs, so a variable without a field (or a field renamed) is a compile error.
const std::vector<ParameterEntry> &parameter_table()
{
    static const std::vector<ParameterEntry> table = [] {
        std::vector<ParameterEntry> t;
#define KT_ENTRY_REAL(vr, id, name, kind, var, hs, st, lo, hi) KT_ENTRY_REAL_##kind(id, name, st)
#define KT_ENTRY_REAL_KT_PARAM(id, name, st) t.push_back({name, KT_PAR_REAL, offsetof(tether_params, id), st});
#define KT_ENTRY_REAL_KT_INPUT(id, name, st)
#define KT_ENTRY_REAL_KT_CALC(id, name, st)
#define KT_ENTRY_REAL_KT_OUTPUT(id, name, st)
#define KT_ENTRY_REAL_KT_LOCAL(id, name, st)
        KT_REAL_VARIABLES(KT_ENTRY_REAL)
#define KT_ENTRY_INT(vr, id, name, kind, var, st, lo, hi) \
    t.push_back({name, KT_PAR_SWITCH, offsetof(tether_params, id), (double)(st)});
        KT_INTEGER_VARIABLES(KT_ENTRY_INT)
#define KT_ENTRY_BOOL(vr, id, name, kind, var, st) KT_ENTRY_BOOL_##kind(id, name, st)
#define KT_ENTRY_BOOL_KT_PARAM(id, name, st) t.push_back({name, KT_PAR_SWITCH, offsetof(tether_params, id), (double)(st)});
#define KT_ENTRY_BOOL_KT_LOCAL(id, name, st)
        KT_BOOLEAN_VARIABLES(KT_ENTRY_BOOL)
        // the only input that is a constant of an experiment
        t.push_back({"L0", KT_PAR_INPUT, offsetof(tether_inputs, L0), 0.0});
        // the measurement (engine.hpp, Measurement)
        const Measurement defaults;
        t.push_back({"offset_measured", KT_PAR_MEASUREMENT, offsetof(Measurement, offset_measured), defaults.offset_measured});
        t.push_back({"offset_input", KT_PAR_MEASUREMENT, offsetof(Measurement, offset_input), defaults.offset_input});
        t.push_back({"input_gain", KT_PAR_MEASUREMENT, offsetof(Measurement, input_gain), defaults.input_gain});
        return t;
    }();
    return table;
}

int parameter_index(const char *name)
{
    if (!name) return -1;
    const auto &t = parameter_table();
    for (std::size_t i = 0; i < t.size(); ++i)
        if (std::strcmp(t[i].name, name) == 0) return (int)i;
    return -1;
}

static tether_model start_model()
{
    // the same as fmu.c's set_start_values
    tether_model M;
    std::memset(&M, 0, sizeof M);
#define KT_START_REAL(vr, id, name, kind, var, hs, st, lo, hi) KT_START_REAL_##kind(id, st)
#define KT_START_REAL_KT_PARAM(id, st) M.p.id = st;
#define KT_START_REAL_KT_INPUT(id, st) M.in.id = st;
#define KT_START_REAL_KT_CALC(id, st)
#define KT_START_REAL_KT_OUTPUT(id, st)
#define KT_START_REAL_KT_LOCAL(id, st)
    KT_REAL_VARIABLES(KT_START_REAL)
#define KT_START_INT(vr, id, name, kind, var, st, lo, hi) M.p.id = st;
    KT_INTEGER_VARIABLES(KT_START_INT)
#define KT_START_BOOL(vr, id, name, kind, var, st) KT_START_BOOL_##kind(id, st)
#define KT_START_BOOL_KT_PARAM(id, st) M.p.id = st;
#define KT_START_BOOL_KT_LOCAL(id, st)
    KT_BOOLEAN_VARIABLES(KT_START_BOOL)
    return M;
}

Setup start_setup()
{
    Setup S;
    // the padding too: the simulation cache compares setups by their bytes
    std::memset(static_cast<void *>(&S), 0, sizeof S);
    S.M = start_model();
    S.meas = Measurement();
    return S;
}

// the bytes a table entry addresses in a setup
static char *field_base(Setup &S, int kind)
{
    if (kind == KT_PAR_INPUT) return reinterpret_cast<char *>(&S.M.in);
    if (kind == KT_PAR_MEASUREMENT) return reinterpret_cast<char *>(&S.meas);
    return reinterpret_cast<char *>(&S.M.p);
}

bool set_parameter(Setup &S, int index, double value, std::string &err)
{
    const auto &t = parameter_table();
    if (index < 0 || index >= (int)t.size()) {
        err = "unknown parameter index " + std::to_string(index);
        return false;
    }
    const ParameterEntry &e = t[(std::size_t)index];
    if (!std::isfinite(value)) {
        err = std::string(e.name) + " = " + std::to_string(value) + " is not finite";
        return false;
    }
    char *base = field_base(S, e.kind);
    if (e.kind == KT_PAR_SWITCH) {
        int v = (int)std::lround(value);
        std::memcpy(base + e.offset, &v, sizeof v);
    } else {
        std::memcpy(base + e.offset, &value, sizeof value);
    }
    return true;
}

double get_parameter(const Setup &S, int index)
{
    const ParameterEntry &e = parameter_table()[(std::size_t)index];
    const char *base = field_base(const_cast<Setup &>(S), e.kind);
    if (e.kind == KT_PAR_SWITCH) {
        int v;
        std::memcpy(&v, base + e.offset, sizeof v);
        return v;
    }
    double v;
    std::memcpy(&v, base + e.offset, sizeof v);
    return v;
}

bool output_offset(const char *name, std::size_t &offset)
{
    if (!name) name = "displacement";
#define KT_OUT(vr, id, nm, kind, var, hs, st, lo, hi) KT_OUT_##kind(id, nm)
#define KT_OUT_KT_PARAM(id, nm)
#define KT_OUT_KT_INPUT(id, nm)
#define KT_OUT_KT_CALC(id, nm) if (std::strcmp(name, nm) == 0) { offset = offsetof(tether_outputs, id); return true; }
#define KT_OUT_KT_OUTPUT(id, nm) KT_OUT_KT_CALC(id, nm)
#define KT_OUT_KT_LOCAL(id, nm) KT_OUT_KT_CALC(id, nm)
    KT_REAL_VARIABLES(KT_OUT)
    // the FMU reports the computed elongation for the payload and load rigs
    if (std::strcmp(name, "elongation") == 0) { offset = offsetof(tether_outputs, elongation); return true; }
    return false;
}

// what a simulation of e reads beside the setup, hashed (Prepared::content)
static ContentHash content_of(const kt_experiment &e, const Prepared &p)
{
    ContentHash h;
    h.add_value(e.n);
    h.add(e.time, sizeof(double) * (std::size_t)e.n);
    h.add_value(e.input_kind);
    if (e.input) h.add(e.input, sizeof(double) * (std::size_t)e.n);
    h.add_value(e.input_der != nullptr);
    if (e.input_der) h.add(e.input_der, 3 * sizeof(double) * (std::size_t)e.n);
    h.add_value(e.periodic_samples);
    h.add_value(e.periodic_tol);
    h.add_value(e.periodic_max_periods);
    h.add(p.outputs.data(), sizeof(std::size_t) * p.outputs.size());
    h.add_value(p.measured_output);
    h.add_value(p.join.value_scale);
    h.add_value(p.join.rate_scale);
    h.add_value(p.join.curvature_scale);
    return h;
}

bool prepare(const kt_experiment &e, int n_out, const char *const *outputs, Prepared &p, std::string &err)
{
    p.e = &e;
    p.base = start_setup();
    if (e.n < 2 || !e.time) { err = "an experiment needs n >= 2 samples and a time grid"; return false; }
    for (int k = 0; k + 1 < e.n; ++k)
        if (!(e.time[k + 1] > e.time[k])) {
            char b[160];
            std::snprintf(b, sizeof b, "time[%d] = %.17g is not after time[%d] = %.17g", k + 1, e.time[k + 1], k, e.time[k]);
            err = b;
            return false;
        }
    if (e.input_kind != KT_INPUT_NONE && e.input_kind != KT_INPUT_FORCE && e.input_kind != KT_INPUT_LOAD) {
        err = "input_kind = " + std::to_string(e.input_kind) + ": expected 0 (none), 1 (force) or 2 (load)";
        return false;
    }
    if (e.input_kind != KT_INPUT_NONE && !e.input) { err = "input_kind is set but input is NULL"; return false; }
    if (e.periodic_samples < 0 || e.periodic_samples == 1 || (e.periodic_samples > 0 && e.n % e.periodic_samples != 0)) {
        err = "periodic_samples = " + std::to_string(e.periodic_samples) + " must be 0 or >= 2 and divide n = " + std::to_string(e.n);
        return false;
    }
    for (int i = 0; i < e.n_settings; ++i) {
        const int idx = parameter_index(e.setting_names[i]);
        if (idx < 0) { err = std::string("setting '") + (e.setting_names[i] ? e.setting_names[i] : "(null)") + "': no such parameter"; return false; }
        if (!set_parameter(p.base, idx, e.setting_values[i], err)) return false;
    }
    p.join = InputJoin();
    if (e.input_kind != KT_INPUT_NONE)
        for (int k = 0; k < e.n; ++k) {
            p.join.value_scale = std::max(p.join.value_scale, std::fabs(e.input[k]));
            if (!e.input_der) continue;
            p.join.rate_scale = std::max(p.join.rate_scale, std::fabs(e.input_der[3 * k]));
            p.join.curvature_scale = std::max(p.join.curvature_scale, std::fabs(e.input_der[3 * k + 1]));
        }
    p.outputs.clear();
    std::size_t measured_off;
    if (!output_offset(e.output, measured_off)) { err = std::string("output '") + e.output + "': not a Real output or local variable"; return false; }
    p.measured_output = n_out <= 0 ? 0 : -1;
    if (n_out <= 0) {
        p.outputs.push_back(measured_off);
    } else {
        for (int i = 0; i < n_out; ++i) {
            std::size_t off;
            if (!output_offset(outputs[i], off)) { err = std::string("output '") + (outputs[i] ? outputs[i] : "(null)") + "': not a Real output or local variable"; return false; }
            if (off == measured_off && p.measured_output < 0) p.measured_output = i;
            p.outputs.push_back(off);
        }
    }
    p.content = content_of(e, p);
    return true;
}

thread_local long long last_simulation_work = 0;

namespace {

// Frees the integrator, and books its work: as the thread's last simulation's, and to the fit's
// limits (if any) on whatever path the simulation ends.
struct IntegratorGuard {
    tether_integrator *I = nullptr;
    const Limits *limits = nullptr;
    long long work() const
    {
        if (!I) return 0;
        integrator_stats st;
        integrator_get_stats(I, &st);
        return st.rhs_evaluations;
    }
    ~IntegratorGuard()
    {
        last_simulation_work = work();
        if (limits) limits->work += last_simulation_work;
        integrator_free(I);
    }
};

// what an importer's fmi2SetReal(input) + fmi2SetRealInputDerivatives does (fmu.c): the value and
// derivatives are stored, a change asks for a restart, and the polynomial starts at the FMU's time.
// The model's input is input_gain * recorded + offset_input (Measurement).
bool set_input(tether_model &M, const Measurement &meas, const kt_experiment &e, int k, double t)
{
    bool changed = false;
    double *value = e.input_kind == KT_INPUT_FORCE ? &M.in.force : &M.in.load;
    double *der = e.input_kind == KT_INPUT_FORCE ? M.in.force_der : M.in.load_der;
    const double v = meas.input_gain * e.input[k] + meas.offset_input;
    if (*value != v) { *value = v; changed = true; }
    for (int j = 0; j < TETHER_INPUT_DERIVATIVE_ORDER; ++j) {
        const double d = e.input_der ? meas.input_gain * e.input_der[3 * k + j] : 0.0;
        if (der[j] != d) { der[j] = d; changed = true; }
    }
    M.in.t_ref = t;
    return changed;
}

// Does input piece k (from t on) carry on piece k_prev (from t_prev on) where it starts: what the
// model's equations see of the input (the force's value; the load's value and rate, which the load
// rig's equations see), and its curvature, the same to InputJoin::tolerance? Then the integrator
// need not restart there.
bool pieces_join(const kt_experiment &e, const Measurement &meas, const InputJoin &join, int k_prev, double t_prev,
                 int k, double t)
{
    const double g = meas.input_gain, h = t - t_prev;
    const double *d = e.input_der ? e.input_der + 3 * k_prev : nullptr;
    const double d1 = d ? g * d[0] : 0.0, d2 = d ? g * d[1] : 0.0, d3 = d ? g * d[2] : 0.0;
    const double reached = g * e.input[k_prev] + meas.offset_input + h * (d1 + h * (d2 / 2.0 + h * d3 / 6.0));
    const double value_tol = InputJoin::tolerance * (std::fabs(g) * join.value_scale + std::fabs(meas.offset_input));
    if (!(std::fabs(g * e.input[k] + meas.offset_input - reached) <= value_tol)) return false;
    const double curvature = d2 + h * d3, curvature_new = e.input_der ? g * e.input_der[3 * k + 1] : 0.0;
    if (!(std::fabs(curvature_new - curvature) <= InputJoin::tolerance * std::fabs(g) * join.curvature_scale))
        return false;
    if (e.input_kind != KT_INPUT_LOAD) return true;
    const double rate = d1 + h * (d2 + h * d3 / 2.0), rate_new = e.input_der ? g * e.input_der[3 * k] : 0.0;
    return std::fabs(rate_new - rate) <= InputJoin::tolerance * std::fabs(g) * join.rate_scale;
}

// The input piece by piece as time goes (integrator_set_input): piece k, from time[k] on, for
// time[k] <= t < time[k + 1] (the last sample's from there on), but never beyond piece `last`: the
// integrator runs up to a sample where the pieces do not join on the piece before it, as the FMU
// does. Pieces are looked up from the last one used.
struct InputPieces {
    const kt_experiment *e;
    const Measurement *meas;
    int last = 0;
    int k = -1;

    int piece_at(double t) const
    {
        int j = std::max(k, 0);
        while (j + 1 < e->n && t >= e->time[j + 1]) ++j;
        while (j > 0 && t < e->time[j]) --j;
        return std::min(j, last);
    }
    void select(double t, tether_model &M)
    {
        const int j = piece_at(t);
        if (j == k) return;
        k = j;
        set_input(M, *meas, *e, j, e->time[j]);
    }
    static void follow(void *ctx, double t, tether_model *M) { static_cast<InputPieces *>(ctx)->select(t, *M); }
};

} // namespace

static double clock_seconds(clockid_t id)
{
    struct timespec ts;
    if (clock_gettime(id, &ts) != 0) return 0.0;
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

bool Limits::expired(long long in_flight) const
{
    if (hit.load()) return true;
    if (work_cap > 0 && (double)(work.load() + in_flight) > work_cap) { hit = 3; return true; }
    if (monotonic > 0 && clock_seconds(CLOCK_MONOTONIC) > monotonic) { hit = 1; return true; }
    if (cpu > 0 && clock_seconds(CLOCK_PROCESS_CPUTIME_ID) > cpu) { hit = 2; return true; }
    if (thread_cpu > 0 && clock_seconds(thread_clock) > thread_cpu) { hit = 2; return true; }
    return false;
}

std::string Limits::message() const
{
    switch (hit.load()) {
    case 2: return "stopped: the CPU-time deadline passed";
    case 3: return "stopped: the work cap passed (" + std::to_string((long long)work_cap) + " evaluations of the equations)";
    default: return "stopped: the wall-time deadline passed";
    }
}

std::string crawl_message(long long cap)
{
    return "the simulation crawled past " + std::to_string(cap) + " evaluations of the equations (its crawl cap)";
}

// the physics of one experiment (simulate below adds the measured column's offset)
static bool simulate_model(const Prepared &p, const tether_model &M0, const Measurement &meas, double *out,
                           std::string &err)
{
    // deadlines: read the clocks every few samples (a reading costs about a microsecond)
    unsigned long polls = 0;
    IntegratorGuard G;
    G.limits = p.limits;
    // the crawl cap, read at every call; the deadlines and the work cap every `every` calls
    auto must_stop = [&](unsigned every) -> bool {
        if (p.crawl_cap > 0 && G.work() > p.crawl_cap) { err = crawl_message(p.crawl_cap); return true; }
        if (!p.limits || (++polls % every) != 0) return false;
        // the simulation's own work so far counts only against a work cap (its integrator's counters)
        if (!p.limits->expired(p.limits->work_cap > 0 ? G.work() : 0)) return false;
        err = p.limits->message();
        return true;
    };
    const kt_experiment &e = *p.e;
    tether_model M = M0; // by value: the integrator reads it through a pointer
    const int n = e.n;
    const int P = e.periodic_samples;
    const bool has_input = e.input_kind != KT_INPUT_NONE;
    // Prepared::continuous_input, but not with the Kawabata law: its reversal memory takes the
    // switches the FMU makes at the samples, where a load that returns to an earlier turning point
    // decides between rejoining its branch and reversing by a hair. The Iwan bank's force is a sum of
    // play operators, continuous in the strain's path: a reversal a hair away moves it by a hair
    const bool carry_on = has_input && p.continuous_input && M.p.hysteresis != HYSTERESIS_KAWABATA;
    const std::size_t n_out = p.outputs.size();
    char msg[1024];
    double y[TETHER_NUMBER_OF_STATES];

    double t = e.time[0];
    // inputs at the first sample are set before the initialisation (the load rig starts from them)
    if (has_input) set_input(M, meas, e, 0, t);
    // fmi2ExitInitializationMode -> initialize_model
    M.in.t_ref = t;
    if (tether_initialize(&M, t, y, msg, sizeof msg) != 0) { err = msg; return false; }
    tether_event_update(&M, t, y, msg, sizeof msg);
    tether_check_range(&M, t, y, msg, sizeof msg);
    G.I = integrator_create(&M, nullptr, nullptr, msg, sizeof msg);
    if (!G.I) { err = msg; return false; }
    bool needs_reset = true;

    // periodic steady state: virtual sample s -> input sample s mod P, time time[s mod P] + (s / P) Tp
    const double Tp = P > 0 ? (n > P ? e.time[P] - e.time[0] : (e.time[P - 1] - e.time[0]) * P / (P - 1.0)) : 0.0;
    auto sample_time = [&](long s) -> double {
        if (P <= 0) return e.time[s];
        return e.time[s % P] + (double)(s / P) * Tp;
    };
    auto input_index = [&](long s) -> int { return P > 0 ? (int)(s % P) : (int)s; };

    long s = 0;           // virtual sample we are at
    std::vector<double> cycle, previous;

    // one step: the inputs of sample s, the outputs there, then fmi2DoStep to sample s + 1
    auto step = [&](double *o, bool last) -> bool {
        if (must_stop(16)) return false;
        bool joined = false; // the input changed here, but its pieces join (Prepared::continuous_input)
        if (s > 0 && has_input && set_input(M, meas, e, input_index(s), t)) {
            joined = carry_on &&
                     pieces_join(e, meas, p.join, input_index(s - 1), sample_time(s - 1), input_index(s), t);
            needs_reset = !joined;
        }
        if (o) {
            tether_outputs to;
            tether_compute_outputs(&M, t, y, &to);
            const char *base = reinterpret_cast<const char *>(&to);
            for (std::size_t j = 0; j < n_out; ++j) std::memcpy(o + j, base + p.outputs[j], sizeof(double));
        }
        if (last) return true;
        // the switches the FMU makes where its input is set, but a restart only where one is made
        if (joined && tether_event_update(&M, t, y, msg, sizeof msg) > 0) needs_reset = true;
        if (needs_reset) {
            tether_event_update(&M, t, y, msg, sizeof msg);
            if (integrator_reset(G.I, t, y) != 0) { err = std::string("could not restart CVODE: ") + integrator_error(G.I); return false; }
            needs_reset = false;
        }
        const double t_next = sample_time(s + 1);
        const double t_end = t + (t_next - t); // fmi2DoStep(t, t_next - t)
        double t_reached = t;
        if (integrator_advance(G.I, t_end, &t_reached, y) != 0) {
            char b[1200];
            std::snprintf(b, sizeof b, "the step from %.17g s to %.17g s stopped at %.17g s: %s", t, t_end, t_reached,
                          integrator_error(G.I));
            err = b;
            return false;
        }
        t = t_end;
        tether_check_range(&M, t, y, msg, sizeof msg);
        ++s;
        return true;
    };

    // Periodic steady state. Run the period's input from the initial state until either
    //  - the states at the end of a period equal those at its start (y(t + Tp) = y(t) makes the
    //    period just run the periodic solution itself), to periodic_tol of each state's largest
    //    magnitude over the period (at least its nominal scale), with the remaining transient
    //    extrapolated from the last two periods' changes (d / (1 - d / d_previous)); not used with
    //    the Kawabata and Iwan laws, whose reversal memory is a state this comparison does not see;
    //  - or one period's output equals the previous one's to periodic_tol of its largest |output|.
    // The period that passed is the record's first period; the rest of the record continues from
    // there. A damped system whose transient dies within one period needs two periods.
    int first_record_sample = 0;
    if (P > 0) {
        constexpr int NS = TETHER_NUMBER_OF_STATES;
        const double tol = e.periodic_tol > 0 ? e.periodic_tol : 1e-7;
        const int max_periods = e.periodic_max_periods > 0 ? e.periodic_max_periods : 400;
        const bool state_test = M.p.hysteresis != HYSTERESIS_KAWABATA && M.p.hysteresis != HYSTERESIS_IWAN;
        double nominal[NS];
        tether_nominals(&M, nominal);
        double d_previous = -1.0;
        cycle.resize((std::size_t)P * n_out);
        for (int c = 0; c < max_periods; ++c) {
            double y_start[NS], y_max[NS];
            const int taut_start = M.d.taut;
            for (int i = 0; i < NS; ++i) {
                y_start[i] = y[i];
                y_max[i] = std::fabs(y[i]);
            }
            for (int j = 0; j < P; ++j) {
                if (!step(&cycle[(std::size_t)j * n_out], false)) return false;
                for (int i = 0; i < NS; ++i) y_max[i] = std::max(y_max[i], std::fabs(y[i]));
            }
            bool converged = false;
            if (state_test && M.d.taut == taut_start) {
                double d = 0.0;
                for (int i = 0; i < NS; ++i) d = std::max(d, std::fabs(y[i] - y_start[i]) / std::max(y_max[i], nominal[i]));
                if (d_previous >= 0.0) {
                    const double ratio = d_previous > 0.0 ? d / d_previous : 0.0;
                    converged = ratio < 1.0 && d / (1.0 - ratio) <= tol;
                }
                d_previous = d;
            } else {
                d_previous = -1.0;
            }
            if (!converged && !previous.empty()) {
                double diff = 0.0, amp = 0.0;
                for (std::size_t i = 0; i < cycle.size(); ++i) {
                    diff = std::max(diff, std::fabs(cycle[i] - previous[i]));
                    amp = std::max(amp, std::fabs(cycle[i]));
                }
                converged = diff <= tol * amp;
            }
            if (converged) {
                std::copy(cycle.begin(), cycle.end(), out);
                first_record_sample = P;
                break;
            }
            previous.swap(cycle);
            cycle.resize((std::size_t)P * n_out);
        }
        if (first_record_sample == P && n == P) return true;
    }
    auto outputs_at = [&](double tt, const double *yy, double *o) {
        tether_outputs to;
        tether_compute_outputs(&M, tt, yy, &to);
        const char *base = reinterpret_cast<const char *>(&to);
        for (std::size_t j = 0; j < n_out; ++j) std::memcpy(o + j, base + p.outputs[j], sizeof(double));
    };
    auto reset = [&]() -> bool {
        if (integrator_reset(G.I, t, y) == 0) return true;
        err = std::string("could not restart CVODE: ") + integrator_error(G.I);
        return false;
    };
    auto advance = [&](double t_end, double t_stop) -> bool {
        double t_reached = t;
        if (integrator_advance_within(G.I, t_end, t_stop, &t_reached, y) == 0) return true;
        char b[1200];
        std::snprintf(b, sizeof b, "the step from %.17g s to %.17g s stopped at %.17g s: %s", t, t_end, t_reached,
                      integrator_error(G.I));
        err = b;
        return false;
    };
    if (P == 0 && carry_on) {
        // the input's pieces followed by time inside the integrator, which restarts only where they
        // do not join or a switch is made; the samples between are read off its interpolant
        InputPieces pieces{&e, &meas};
        integrator_set_input(G.I, InputPieces::follow, &pieces);
        int k = 0;
        while (k < n - 1) {
            int b = k + 1; // the next sample where the pieces do not join (or the last)
            while (b < n - 1 && pieces_join(e, meas, p.join, b - 1, e.time[b - 1], b, e.time[b])) ++b;
            pieces.last = b - 1;
            for (int j = k; j < b; ++j) {
                if (must_stop(16)) return false;
                pieces.select(t, M);
                outputs_at(t, y, out + (std::size_t)j * n_out);
                // the switches the FMU makes where its input is set; a restart where the pieces do
                // not join, or where a switch is made (from the interpolant's states there)
                const int switches = tether_event_update(&M, t, y, msg, sizeof msg);
                if ((j == k || switches > 0) && !reset()) return false;
                if (!advance(e.time[j + 1], e.time[b])) return false;
                t = e.time[j + 1];
                tether_check_range(&M, t, y, msg, sizeof msg);
            }
            k = b;
        }
        pieces.last = n - 1;
        pieces.select(t, M);
        outputs_at(t, y, out + (std::size_t)(n - 1) * n_out);
        return true;
    }
    const int stride = (P == 0 && !has_input) ? std::max(1, p.stride) : 1;
    if (stride == 1) {
        for (int k = first_record_sample; k < n; ++k)
            if (!step(out + (std::size_t)k * n_out, k == n - 1)) return false;
        return true;
    }
    // fast mode: one integrator call per chunk of samples, Hermite interpolation inside
    constexpr int NS = TETHER_NUMBER_OF_STATES;
    int k = 0;
    while (k < n - 1) {
        if (must_stop(1)) return false;
        const int k2 = std::min(n - 1, k + stride);
        if (needs_reset) {
            tether_event_update(&M, t, y, msg, sizeof msg);
            if (integrator_reset(G.I, t, y) != 0) { err = std::string("could not restart CVODE: ") + integrator_error(G.I); return false; }
            needs_reset = false;
        }
        outputs_at(t, y, out + (std::size_t)k * n_out);
        const tether_model M_saved = M;
        double y0[NS], f0[NS], f1[NS];
        std::memcpy(y0, y, sizeof y0);
        tether_derivatives(&M, t, y0, f0);
        integrator_stats st0, st1;
        integrator_get_stats(G.I, &st0);
        const double t0c = t, t1c = e.time[k2];
        double t_reached = t;
        if (integrator_advance(G.I, t1c, &t_reached, y) != 0) {
            char b[1200];
            std::snprintf(b, sizeof b, "the step from %.17g s to %.17g s stopped at %.17g s: %s", t, t1c, t_reached,
                          integrator_error(G.I));
            err = b;
            return false;
        }
        integrator_get_stats(G.I, &st1);
        if (st1.events != st0.events) {
            // a discrete switch inside the chunk: redo it sample by sample from its start
            M = M_saved;
            std::memcpy(y, y0, sizeof y0);
            t = t0c;
            s = k;
            needs_reset = true;
            for (int j = k; j < k2; ++j)
                if (!step(out + (std::size_t)j * n_out, false)) return false;
            k = k2;
            continue;
        }
        t = t1c;
        s = k2;
        tether_derivatives(&M, t, y, f1);
        const double h = t1c - t0c;
        for (int j = k + 1; j < k2; ++j) {
            const double u = (e.time[j] - t0c) / h, u2 = u * u, u3 = u2 * u;
            const double h00 = 2 * u3 - 3 * u2 + 1, h10 = u3 - 2 * u2 + u, h01 = -2 * u3 + 3 * u2, h11 = u3 - u2;
            double yi[NS];
            for (int i = 0; i < NS; ++i) yi[i] = h00 * y0[i] + h10 * h * f0[i] + h01 * y[i] + h11 * h * f1[i];
            outputs_at(e.time[j], yi, out + (std::size_t)j * n_out);
        }
        k = k2;
    }
    outputs_at(t, y, out + (std::size_t)(n - 1) * n_out);
    return true;
}

void add_measured_offset(const Prepared &p, double offset, double *out)
{
    if (offset != 0.0 && p.measured_output >= 0) {
        const std::size_t n_out = p.outputs.size();
        for (int k = 0; k < p.e->n; ++k) out[(std::size_t)k * n_out + (std::size_t)p.measured_output] += offset;
    }
}

bool simulate_physics(const Prepared &p, const Setup &S, double *out, std::string &err)
{
    if (!simulate_model(p, S.M, S.meas, out, err)) return false;
    add_measured_offset(p, S.meas.offset_measured, out);
    return true;
}

} // namespace kt
