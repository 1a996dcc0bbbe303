// The C interface of the identification engine: parameter table and simulation (kt_fit is in fit.cpp).
#include <cmath>
#include <exception>
#include <limits>
#include <string>

#include "identify/engine.hpp"

namespace kt {
extern thread_local std::string last_error;
}

extern "C" {

int kt_api_version(void) { return KT_IDENTIFY_API_VERSION; }

int kt_parameter_count(void) { return (int)kt::parameter_table().size(); }

const char *kt_parameter_name(int i, int *kind)
{
    const auto &t = kt::parameter_table();
    if (i < 0 || i >= (int)t.size()) return nullptr;
    if (kind) *kind = t[(std::size_t)i].kind;
    return t[(std::size_t)i].name;
}

int kt_parameter_index(const char *name) { return kt::parameter_index(name); }

double kt_parameter_start(const char *name)
{
    const int i = kt::parameter_index(name);
    if (i < 0) return std::numeric_limits<double>::quiet_NaN();
    return kt::get_parameter(kt::start_setup(), i);
}

const char *kt_last_error(void) { return kt::last_error.c_str(); }

long long kt_last_simulation_work(void) { return kt::last_simulation_work; }

long long kt_simulation_cache_bytes(long long bytes) { return kt::set_simulation_cache_bytes(bytes); }

void kt_simulation_cache_counts(long long *reused, long long *made)
{
    long long r = 0, m = 0;
    kt::simulation_cache_counts(r, m);
    if (reused) *reused = r;
    if (made) *made = m;
}

int kt_simulate_outputs(const kt_experiment *e, int n_par, const char *const *names, const double *values, int n_out,
                        const char *const *outputs, double *out)
{
    std::string &err = kt::last_error;
    err.clear();
    kt::last_simulation_work = 0; // a call refused before it simulates does no work
    try {
        if (!e || !out) { err = "kt_simulate: experiment and out must not be NULL"; return -1; }
        kt::Prepared p;
        if (!kt::prepare(*e, n_out, outputs, p, err)) return -1;
        kt::Setup S = p.base;
        for (int i = 0; i < n_par; ++i) {
            const int idx = kt::parameter_index(names[i]);
            if (idx < 0) { err = std::string("parameter '") + (names[i] ? names[i] : "(null)") + "': no such parameter"; return -1; }
            if (!kt::set_parameter(S, idx, values[i], err)) return -1;
        }
        return kt::simulate(p, S, out, err) ? 0 : -1;
    } catch (const std::exception &ex) {
        err = std::string("kt_simulate: ") + ex.what();
        return -1;
    }
}

int kt_simulate(const kt_experiment *e, int n_par, const char *const *names, const double *values, double *out)
{
    return kt_simulate_outputs(e, n_par, names, values, 0, nullptr, out);
}

int kt_bouc_wen_path(double A, double beta, double gamma, const double *x, int n, int periodic, double *z)
{
    kt::last_error.clear();
    if (!x || !z || n < 1) { kt::last_error = "kt_bouc_wen_path: need n >= 1 samples and x, z not NULL"; return -1; }
    boucwen_path(A, beta, gamma, x, n, periodic, z);
    return 0;
}

} // extern "C"
