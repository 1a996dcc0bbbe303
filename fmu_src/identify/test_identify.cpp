// C-interface tests of the identification engine: the parameter table, a simulation against the
// linear oscillator's closed form, and a small fit that recovers known parameters.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

#include "identify/identify.h"

static int failures = 0;
#define CHECK(cond, ...)                                                                          \
    do {                                                                                          \
        if (!(cond)) { std::printf("FAIL %s:%d: ", __FILE__, __LINE__); std::printf(__VA_ARGS__); std::printf("\n"); ++failures; } \
    } while (0)

int main()
{
    // table: every tether_params field named in modelDescription.xml is addressable by name
    const char *must[] = {"rtol", "m", "g", "x0", "v0", "EA", "a1", "a2", "a3", "c0", "c1", "c2", "bw_A", "bw_beta",
                          "bw_gamma", "bw_n", "z0", "rig", "stiffness", "damping", "hysteresis", "L0"};
    for (const char *n : must) CHECK(kt_parameter_index(n) >= 0, "parameter %s missing", n);
    CHECK(kt_parameter_index("nonsense") == -1, "unknown name accepted");
    CHECK(kt_parameter_start("m") == 4.3, "start of m = %g", kt_parameter_start("m"));

    // linear undamped payload oscillator, no gravity: x = x0 cos(w t), w = sqrt(EA / (L0 m))
    const int n = 2001;
    std::vector<double> t(n), x(n);
    for (int i = 0; i < n; ++i) t[i] = 1e-3 * i;
    const char *sn[] = {"rig", "stiffness", "damping", "hysteresis", "slack", "m", "g", "x0", "L0", "c0", "EA", "rtol"};
    const double sv[] = {2, 1, 1, 1, 0, 2.0, 0.0, 0.01, 10.0, 0.0, 3000.0, 1e-10};
    kt_experiment e;
    std::memset(&e, 0, sizeof e);
    e.n_settings = 12;
    e.setting_names = sn;
    e.setting_values = sv;
    e.n = n;
    e.time = t.data();
    e.output = "displacement";
    CHECK(kt_simulate(&e, 0, nullptr, nullptr, x.data()) == 0, "simulate: %s", kt_last_error());
    const double w = std::sqrt(3000.0 / (10.0 * 2.0));
    double err = 0;
    for (int i = 0; i < n; ++i) err = std::fmax(err, std::fabs(x[i] - 0.01 * std::cos(w * t[i])));
    CHECK(err < 1e-9, "closed form: max error %g", err);

    // fit EA and c0 back from a damped trace
    const char *pn[] = {"EA", "c0"};
    const double truth[] = {3000.0, 0.8};
    std::vector<double> meas(n);
    CHECK(kt_simulate(&e, 2, pn, truth, meas.data()) == 0, "simulate: %s", kt_last_error());
    e.measured = meas.data();
    const double lo[] = {100.0, 1e-3}, hi[] = {1e5, 100.0}, st[] = {2700.0, 2.0};
    kt_fit_options o;
    kt_fit_default_options(&o);
    double val[2], se[2], cov[4], cor[4], svals[2], svec[4], hist[200];
    int flags[2], dflags[2];
    kt_fit_result r;
    std::memset(&r, 0, sizeof r);
    r.values = val; r.std_error = se; r.covariance = cov; r.correlation = cor; r.singular_values = svals;
    r.singular_vectors = svec; r.unidentifiable = flags; r.direction_flags = dflags; r.cost_history = hist;
    r.cost_history_capacity = 200;
    const int rc = kt_fit(&e, 1, 2, pn, lo, hi, st, nullptr, &o, &r);
    CHECK(rc == 0, "fit rc %d: %s / %s", rc, kt_last_error(), r.message);
    CHECK(std::fabs(val[0] / 3000.0 - 1) < 1e-6 && std::fabs(val[1] / 0.8 - 1) < 1e-5, "fit: EA %g c0 %g", val[0], val[1]);
    std::printf("fit: EA %.9g c0 %.9g, %d evaluations, %.3f s, %s\n", val[0], val[1], r.evaluations, r.seconds, r.message);
    if (failures) std::printf("%d failure(s)\n", failures);
    else std::printf("all passed\n");
    return failures ? 1 : 0;
}
