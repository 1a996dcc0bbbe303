// Internal C++ interface of the identification engine (see identify.h for the C interface).
#ifndef KT_IDENTIFY_ENGINE_HPP
#define KT_IDENTIFY_ENGINE_HPP

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <time.h>

extern "C" {
#include "physics/tether.h"
}
#include "identify/identify.h"

namespace kt {

struct ParameterEntry {
    const char *name;
    int kind;          // KT_PAR_*
    std::size_t offset; // in tether_params (REAL, SWITCH), tether_inputs (INPUT) or Measurement (MEASUREMENT)
    double start;
};

// How a record relates to the model, beside the physics (identify.h, KT_PAR_MEASUREMENT): the
// model is driven by input_gain * recorded input + offset_input (derivatives times input_gain) and
// the measured column is compared with the model's output + offset_measured. Not FMU variables:
// the FMU simulates physics, the measurement belongs to identification.
struct Measurement {
    double offset_measured = 0.0;
    double offset_input = 0.0;
    double input_gain = 1.0;
};

// Everything a simulation of one experiment depends on: the model and the measurement.
struct Setup {
    tether_model M;
    Measurement meas;
};

const std::vector<ParameterEntry> &parameter_table();
int parameter_index(const char *name);
// the model of modelDescription.xml's start values (what fmi2Instantiate sets), the measurement's defaults
Setup start_setup();
bool set_parameter(Setup &S, int index, double value, std::string &err);
double get_parameter(const Setup &S, int index);
// offset of a double field of tether_outputs for an output variable name; false if unknown
bool output_offset(const char *name, std::size_t &offset);

// Deadlines of a fit (kt_fit_options.deadline_*, max_rhs_evaluations): a simulation checks them as
// it goes and fails with the error below once one has passed; `hit` says which did (1 wall, 2 CPU,
// 3 work), for the message. Work is counted in evaluations of the model's equations, summed over the
// fit's simulations: the same fit does the same work on a busy machine and an idle one.
struct Limits {
    double monotonic = 0, cpu = 0; // clock readings in seconds, 0 = none
    double thread_cpu = 0;         // on the CPU clock of the thread that called kt_fit
    clockid_t thread_clock{};
    double work_cap = 0;           // equation evaluations, 0 = none
    mutable std::atomic<long long> work{0}; // of the simulations that have ended
    mutable std::atomic<int> hit{0};
    bool expired(long long in_flight = 0) const; // reads the clocks and the work; sets hit
    std::string message() const;
};

// the error of a simulation stopped at its crawl cap (Prepared::crawl_cap)
std::string crawl_message(long long cap);

// the equation evaluations of the last simulation on this thread (kt_last_simulation_work)
extern thread_local long long last_simulation_work;

// Where a record's input pieces join: at a sample, the new piece carries on the last one if it
// starts where that one arrived, to `tolerance` of the record's largest |input| (of its largest
// |input rate|, for the load, whose rate the load rig's equations see as well), and with the
// curvature it arrived with (to `tolerance` of the largest |input curvature|): where the curvature
// jumps (a PCHIP load's hold meeting a ramp) an integrator that carried on could step over the
// whole next piece and never see it (a creep record's load steps, 2026-12-01).
struct InputJoin {
    static constexpr double tolerance = 1e-9;
    // max |input|, max |input_der[., 0]|, max |input_der[., 1]| of the record
    double value_scale = 0, rate_scale = 0, curvature_scale = 0;
};

// Two 64-bit hashes of data (FNV-1a over 8-byte words, and a multiply-xorshift mix): together they
// name an experiment's data beyond any chance of two records sharing them (simulation_cache.cpp)
struct ContentHash {
    std::uint64_t a = 1469598103934665603ULL, b = 0x9E3779B97F4A7C15ULL;
    void add(const void *data, std::size_t bytes);
    template <class T> void add_value(const T &v) { add(&v, sizeof v); }
};

// An experiment ready to run: the model with the experiment's settings, the output offsets.
struct Prepared {
    const kt_experiment *e = nullptr;
    Setup base{};
    std::vector<std::size_t> outputs;
    int measured_output = 0; // which of outputs is the measured column (offset_measured); -1 none
    // fit speed-up (1 = off, the FMU's exact step sequence): without inputs, integrate `stride`
    // samples per integrator call and fill the samples between by cubic Hermite interpolation of
    // the states (a chunk with a discrete event is redone sample by sample)
    int stride = 1;
    const Limits *limits = nullptr; // checked during the simulation (NULL = none)
    // evaluations of the equations a simulation may need before it fails as one that crawled
    // (0 = no bound): set by a fit from its start's work (kt_fit_options.crawl_factor), between
    // the batches of simulations that read it
    mutable long long crawl_cap = 0;
    // fit speed-up (false = off, the FMU's exact step sequence): with an input, integrate on through
    // the samples where the input's pieces join (InputJoin) instead of restarting the integrator at
    // every sample as an importer's fmi2SetReal does (a piece that jumps still restarts it); not
    // periodic: the integrator follows the pieces by time and its steps pass the samples, which are
    // read off its interpolant. Not with the Kawabata law (simulate.cpp says why)
    bool continuous_input = false;
    InputJoin join;
    // what a simulation reads of the experiment (its grid, input, periodic settings, outputs), hashed
    // by prepare: with the setup and the speed-ups above, the key of the simulation cache
    ContentHash content;
};
bool prepare(const kt_experiment &e, int n_out, const char *const *outputs, Prepared &p, std::string &err);

// Run the experiment on the setup S (parameters set); out is n x outputs.size() row-major, the
// measured column with offset_measured added. A simulation made before in this process with the same
// experiment data, setup and speed-ups is read back (the same bits; simulation_cache.cpp), its work
// booked to p.limits as the simulation's own; simulate_physics always simulates.
bool simulate(const Prepared &p, const Setup &S, double *out, std::string &err);
bool simulate_physics(const Prepared &p, const Setup &S, double *out, std::string &err);

// The simulation cache: at most this many bytes, the least recently used dropped first
constexpr long long SIMULATION_CACHE_DEFAULT_BYTES = 256LL << 20;
// its bound in bytes (0: off, emptied); returns the bound before
long long set_simulation_cache_bytes(long long bytes);
// the simulations read back from it, and those made, since the process started
void simulation_cache_counts(long long &reused, long long &made);

// What simulate adds to its outputs out (n x outputs.size()) for offset_measured: the offset to the
// measured column (the outputs of a simulation with offset_measured 0 become those with `offset`).
void add_measured_offset(const Prepared &p, double offset, double *out);

} // namespace kt

#endif
