// Internal C++ interface of the identification engine (see identify.h for the C interface).
#ifndef KT_IDENTIFY_ENGINE_HPP
#define KT_IDENTIFY_ENGINE_HPP

#include <atomic>
#include <cstddef>
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
    std::size_t offset; // in tether_params (REAL, SWITCH) or tether_inputs (INPUT)
    double start;
};

const std::vector<ParameterEntry> &parameter_table();
int parameter_index(const char *name);
// the model of modelDescription.xml's start values (what fmi2Instantiate sets)
tether_model start_model();
bool set_parameter(tether_model &M, int index, double value, std::string &err);
double get_parameter(const tether_model &M, int index);
// offset of a double field of tether_outputs for an output variable name; false if unknown
bool output_offset(const char *name, std::size_t &offset);

// Deadlines of a fit (kt_fit_options.deadline_*): a simulation checks them as it goes and fails
// with the error below once one has passed; `hit` says which did (1 wall, 2 CPU), for the message.
struct Limits {
    double monotonic = 0, cpu = 0; // clock readings in seconds, 0 = none
    double thread_cpu = 0;         // on the CPU clock of the thread that called kt_fit
    clockid_t thread_clock{};
    mutable std::atomic<int> hit{0};
    bool any() const { return monotonic > 0 || cpu > 0 || thread_cpu > 0; }
    bool expired() const;          // reads the clocks; sets hit
    std::string message() const;
};

// An experiment ready to run: the model with the experiment's settings, the output offsets.
struct Prepared {
    const kt_experiment *e = nullptr;
    tether_model base{};
    std::vector<std::size_t> outputs;
    // fit speed-up (1 = off, the FMU's exact step sequence): without inputs, integrate `stride`
    // samples per integrator call and fill the samples between by cubic Hermite interpolation of
    // the states (a chunk with a discrete event is redone sample by sample)
    int stride = 1;
    const Limits *limits = nullptr; // checked during the simulation (NULL = none)
};
bool prepare(const kt_experiment &e, int n_out, const char *const *outputs, Prepared &p, std::string &err);

// Run the experiment on the model M (parameters set); out is n x outputs.size() row-major.
bool simulate(const Prepared &p, const tether_model &M, double *out, std::string &err);

} // namespace kt

#endif
