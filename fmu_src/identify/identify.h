/* KevlarTether identification engine: the C interface (for Python through ctypes, or any C caller).
 *
 * The engine simulates the FMU's own physics (fmu_src/physics + fmu_src/solver, linked from the
 * static library tether_core) in batch, exactly as the FMU's co-simulation does when it is driven
 * with one fmi2DoStep per sample, and fits chosen parameters by Levenberg-Marquardt.
 *
 * Parameters are addressed by their modelDescription.xml names (kt_parameter_name lists them):
 * every Real parameter (fields of tether_params), the Integer/Boolean switches (rig, stiffness,
 * damping, hysteresis, integrator, creep, slack; set as doubles, rounded), the input L0 and the
 * measurement parameters offset_measured, offset_input, input_gain (KT_PAR_MEASUREMENT).
 *
 * Plain C types only; every array is owned by the caller. Thread-safe (no global state besides a
 * thread-local error message).
 */
#ifndef KT_IDENTIFY_H
#define KT_IDENTIFY_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(__GNUC__)
#define KT_API __attribute__((visibility("default")))
#else
#define KT_API
#endif

#define KT_IDENTIFY_API_VERSION 10

/* ---- parameter table ------------------------------------------------------------------------ */
#define KT_PAR_REAL 0   /* a Real parameter: a double field of tether_params */
#define KT_PAR_SWITCH 1 /* an Integer/Boolean parameter: an int field of tether_params */
#define KT_PAR_INPUT 2  /* a Real input that is constant in an experiment (L0) */
/* a measurement parameter of an experiment, not an FMU variable (the FMU simulates physics; how the
 * record relates to it belongs to identification):
 *   offset_measured (start 0): the measured column = the model's output + offset_measured;
 *   offset_input (start 0), input_gain (start 1): the model is driven by
 *     input_gain * recorded input + offset_input, its derivatives by input_gain * recorded ones.
 * Set and fitted by name like any other parameter. */
#define KT_PAR_MEASUREMENT 3
KT_API int kt_api_version(void);
KT_API int kt_parameter_count(void);
/* name of entry i (NULL if out of range); *kind one of KT_PAR_* (kind may be NULL) */
KT_API const char *kt_parameter_name(int i, int *kind);
/* index of a name, -1 if unknown */
KT_API int kt_parameter_index(const char *name);
/* start value of modelDescription.xml for a name (NaN if unknown) */
KT_API double kt_parameter_start(const char *name);

/* ---- one experiment ------------------------------------------------------------------------- */
/* Input channel of an experiment */
#define KT_INPUT_NONE 0  /* free vibration */
#define KT_INPUT_FORCE 1 /* payload rig: force on the payload */
#define KT_INPUT_LOAD 2  /* load rig: applied tension */

typedef struct {
    /* fixed settings of this experiment, applied over modelDescription.xml's start values
     * (e.g. rig, stiffness, damping, hysteresis, m, g, x0, v0, L0, rtol, offset_measured) */
    int n_settings;
    const char *const *setting_names;
    const double *setting_values;
    /* sample grid, strictly increasing, n >= 2 */
    int n;
    const double *time;
    /* input: value at each sample and its derivatives of order 1..3 at each sample (row-major
     * n x 3, e.g. a cubic spline's; NULL = zeros). At sample k the engine sets the input to
     * input[k] with derivatives input_der[3k..3k+2] from t_k on, exactly as an importer calling
     * fmi2SetReal + fmi2SetRealInputDerivatives before fmi2DoStep(t_k, t_{k+1} - t_k) does. */
    int input_kind;
    const double *input;
    const double *input_der;
    /* output compared with the measurement: a modelDescription.xml variable name, e.g.
     * "displacement", "elongation", "tension" (NULL = "displacement") */
    const char *output;
    const double *measured; /* n samples (needed by kt_fit, unused by kt_simulate) */
    double weight;          /* residuals are weight * (simulated - measured); 0 means 1 */
    /* periodic steady state: the record is whole periods of this many samples (0 = not periodic).
     * The first period's input is repeated from the initial state until the states at the end of a
     * period equal those at its start (remaining transient extrapolated from the last two periods),
     * or the output of one period equals the previous one's, to periodic_tol (0 = 1e-7) relative,
     * at most periodic_max_periods periods (0 = 400). That period is the record's first; the record
     * continues from there (simulate.cpp says exactly how). */
    int periodic_samples;
    double periodic_tol;
    int periodic_max_periods;
    /* n factors on the residuals beside weight (NULL = all 1): a sample of factor 0 is left out of
     * the fit (a held-out part inside the record); the simulation still runs through it */
    const double *sample_weight;
} kt_experiment;

/* Simulate one experiment with the parameters names[i] = values[i] (after the experiment's own
 * settings); out[k] = the output at time[k] (+ offset_measured). Returns 0, or -1 with kt_last_error(). */
KT_API int kt_simulate(const kt_experiment *e, int n_par, const char *const *names, const double *values,
                       double *out);
/* The same, several outputs at once: out is row-major n x n_out, outputs named like kt_experiment.output
 * (offset_measured is added to the one that is kt_experiment.output, the measured column, only). */
KT_API int kt_simulate_outputs(const kt_experiment *e, int n_par, const char *const *names, const double *values,
                               int n_out, const char *const *outputs, double *out);
KT_API const char *kt_last_error(void);
/* The evaluations of the model's equations that the last kt_simulate or kt_simulate_outputs on this
 * thread made (its work, the unit of kt_fit_options.max_rhs_evaluations). */
KT_API long long kt_last_simulation_work(void);

/* The simulations made in this process are kept, at most this many bytes of them (the least
 * recently used dropped first; 256 MiB to begin with), and a simulation asked for again (the same
 * experiment data, parameters and speed-ups) is read back: the same bits, its work booked as its own
 * (kt_last_simulation_work, a fit's max_rhs_evaluations). 0 switches this off and empties it.
 * Returns the bound before. */
KT_API long long kt_simulation_cache_bytes(long long bytes);
/* the simulations read back and those made since the process started */
KT_API void kt_simulation_cache_counts(long long *reused, long long *made);

/* z of the Bouc-Wen law (n = 1) along the displacement path x[0..n-1] (physics/laws.h,
 * boucwen_path): the hysteretic force an equation-error estimate of (A, beta, gamma) needs.
 * Returns 0, or -1 with kt_last_error() for a bad argument. */
KT_API int kt_bouc_wen_path(double A, double beta, double gamma, const double *x, int n, int periodic, double *z);

/* ---- fitting -------------------------------------------------------------------------------- */
#define KT_SCALE_AUTO 0   /* log if the bounds (or the start) keep one sign, else linear */
#define KT_SCALE_LOG 1    /* theta = log|p| (the bounds must not contain 0) */
#define KT_SCALE_LINEAR 2 /* theta = p / |start| (or / 1 if start is 0) */

/* Progress of a fit: called on the caller's thread after every Levenberg-Marquardt iteration of
 * start `start` (0 = the given start), horizon stage `stage` (0-based, of n_stages), with the cost
 * 0.5 sum r^2 and the simulations so far. Return 0 to go on, nonzero to stop (kt_fit then returns
 * -1 with kt_last_error() "kt_fit: stopped by the progress callback"). */
typedef int (*kt_progress_fn)(void *ctx, int start, int stage, int n_stages, int iteration, double cost,
                              long evaluations);

typedef struct {
    int max_iterations;      /* LM iterations per start (default 100) */
    double ftol;             /* stop when the relative cost decrease < ftol (default 1e-10) */
    double xtol;             /* stop when the scaled step < xtol (default 1e-9) */
    double gtol;             /* stop when |J^T r|_inf / cost < gtol (default 1e-12) */
    double fd_step;          /* forward-difference step in scaled parameters (default 1e-3) */
    int central_differences; /* 0: forward differences; 1: central differences throughout (twice
                                the simulations); 2 (default): forward until the last stage stops,
                                then central differences polish the optimum and give the statistics */
    int n_starts;            /* several starts (1 = only the given start; default 1) */
    double start_spread;     /* random starts: uniform in the box when it is finite in the scaled
                                coordinates, else start +- start_spread in them (default 0.5) */
    unsigned seed;           /* random starts (default 1) */
    int n_threads;           /* parallel Jacobian columns (0 = hardware cores) */
    double rtol;             /* if > 0, overrides every experiment's rtol during the fit */
    double singular_rel_tol; /* flag directions with sigma_i / sigma_max below this (default 1e-4) */
    double max_rel_std;      /* flag directions whose standard deviation in scaled coordinates (for
                                log-scaled parameters: relative) exceeds this (default 0.5) */
    double stat_tol;         /* stop when an accepted step lowers the cost by less than stat_tol * s^2,
                                s^2 = 2 cost / (N - k): far below what a standard error means
                                (default 1e-2; 0 = off) */
    int output_stride;       /* speed-up for experiments without input (free vibration): integrate
                                this many samples per solver call and interpolate the states between
                                (cubic Hermite; chunks with a discrete event are redone sample by
                                sample). 0 or 1 = the FMU's exact step sequence (default 1) */
    int horizon_stages;      /* m > 1: fit the first 1/2^(m-1) of each non-periodic record, then
                                1/2^(m-2), ..., then all of it, each stage starting where the last
                                ended (keeps the cost of an oscillation unimodal in its frequency;
                                default 1 = whole records only) */
    int verbose;             /* 1: progress lines on stderr */
    kt_progress_fn progress; /* called after every LM iteration (NULL = none); nonzero stops the fit */
    void *progress_ctx;
    /* Deadlines, as readings of POSIX clocks in seconds (0 = none): the fit stops, with kt_fit
     * returning -1 and kt_last_error() "kt_fit: stopped: the wall-time deadline passed" (or
     * "CPU-time"), as soon as one passes, checked inside every simulation as well as between
     * iterations (an iteration whose simulations crawl can take far longer than the deadline). */
    double deadline_monotonic; /* CLOCK_MONOTONIC */
    double deadline_cpu;       /* CLOCK_PROCESS_CPUTIME_ID (this process, all threads) */
    double deadline_thread_cpu; /* CLOCK_THREAD_CPUTIME_ID of the thread calling kt_fit: with
                                   n_threads = 1 the fit's own CPU time, whatever else the process
                                   runs beside it (fits side by side on several threads) */
    int continuous_input;    /* speed-up for experiments with an input (forced, load and creep tests):
                                1 (default) = where the input's next piece starts where the last one
                                arrived (the force's value; the load's value and rate; to 1e-9 of
                                the record's largest), the integrator goes on without a restart; a
                                record that is not periodic gives the integrator its input piece by
                                piece as time goes, lets its steps pass the samples and reads them
                                off its interpolant. Within the integration tolerance of the FMU's
                                trajectory. Not with the Kawabata law (its reversal memory takes
                                the switches the FMU makes at every sample). 0 =
                                restart the integrator at every sample, as the FMU does when an
                                importer sets the input (kt_simulate's exact step sequence) */
    int broyden_updates;     /* speed-up of the forward-difference iterations (not of central ones,
                                which polish the optimum): after an accepted step, update the
                                Jacobian by Broyden's rank-one secant formula instead of computing
                                it anew by finite differences (one simulation per parameter), at
                                most this many times in a row. An updated Jacobian never ends a
                                fit: where it would (gradient or step small, a small decrease, no
                                decrease), the finite-difference one is computed there and the
                                iteration redone. 0 = a finite-difference Jacobian every iteration */
    double max_rhs_evaluations; /* a cap on the fit's work (0 = none): the evaluations of the model's
                                   equations summed over all its simulations. Stops the fit like a
                                   deadline ("kt_fit: stopped: the work cap passed ..."), but the same
                                   fit stops at the same point however busy the machine is */
    double crawl_factor;     /* a trial point whose simulation needs more than this many times the
                                work of the Levenberg-Marquardt run's start (per experiment, and at
                                least 2 evaluations per sample) fails like one that does not
                                simulate: its step is refused and the fit goes on with a shorter
                                one, instead of crawling through equations turned stiff until the
                                work cap or a deadline ends the whole fit (default 100; 0 = off) */
} kt_fit_options;

KT_API void kt_fit_default_options(kt_fit_options *o);

/* Results; every array is allocated by the caller with the sizes given (k = number of free
 * parameters); any pointer may be NULL if not wanted. Matrices are row-major. */
typedef struct {
    double *values;            /* k: fitted parameters */
    double *covariance;        /* k x k: s^2 (J^T J)^-1 in the physical parameters */
    double *std_error;         /* k */
    double *ci_low, *ci_high;  /* k: 95 % intervals (Student t, linearised) */
    double *correlation;       /* k x k */
    double *singular_values;   /* k: of the Jacobian in scaled parameters, decreasing */
    double *singular_vectors;  /* k x k: column i = direction i (scaled parameters) */
    int *direction_flags;      /* k: 1 if direction i is not determined by the data */
    int *unidentifiable;       /* k: 1 if the parameter takes part in an undetermined direction */
    double *cost_history;      /* cost_history_capacity: cost (0.5 sum r^2) after each accepted step */
    int cost_history_capacity;
    /* filled by kt_fit */
    int cost_history_length;
    double cost;               /* 0.5 sum r^2 at the optimum */
    double rms;                /* sqrt(sum r^2 / N) */
    double sigma2;             /* residual variance s^2 = sum r^2 / (N - k) */
    double condition;          /* sigma_max / sigma_min */
    int n_residuals, dof;
    int evaluations;           /* simulations of the whole data set (each = one per experiment) */
    int jacobian_evaluations;  /* of evaluations: those of finite-difference Jacobian columns */
    int iterations;            /* LM iterations, all starts */
    int best_start;            /* which start gave the optimum (0 = the given start) */
    int status;                /* 0 converged (every horizon stage), 1 max iterations (in any stage), < 0 failure */
    double seconds;            /* wall-clock time of the fit */
    double cpu_seconds;        /* CPU time of the fit: the calling thread's and its helper threads' */
    char message[256];         /* why it stopped */
    char report[4096];         /* the undetermined directions, named, one per line */
    long long rhs_evaluations; /* the fit's work: evaluations of the model's equations, all simulations */
} kt_fit_result;

/* Fit the k parameters names[] (shared by all experiments) to the n_exp experiments jointly.
 * lower/upper: box bounds (may be -inf/+inf; NULL = none); start: k start values; scaling: k of
 * KT_SCALE_* (NULL = auto). Returns 0 (converged), 1 (stopped at max_iterations) or -1 (error,
 * kt_last_error()). */
KT_API int kt_fit(const kt_experiment *experiments, int n_exp, int k, const char *const *names,
                  const double *lower, const double *upper, const double *start, const int *scaling,
                  const kt_fit_options *options, kt_fit_result *result);

#ifdef __cplusplus
}
#endif

#endif
