/* The CVODE wrapper: integrates a tether model (physics/tether.h) to a given time, locating
 * every state event (slack entry and exit, Kawabata reversals) by root finding, switching the
 * model's discrete state there and re-initialising CVODE. Knows nothing of FMI. */
#ifndef KT_SOLVER_INTEGRATOR_H
#define KT_SOLVER_INTEGRATOR_H

#include <stddef.h>

#include "physics/tether.h"

typedef struct tether_integrator tether_integrator;

/* The model's rtol is the accuracy asked of the solution over a run; CVODE controls the error of
 * each step, which accumulates over the steps of a run. Measured on an undamped oscillator over
 * 100 periods: local tolerance 1e-10 drifts the energy by 3.8e-7, 1e-12 by 2.5e-9. So CVODE gets
 * rtol times this factor (and never less than the smallest tolerance it can honour). */
#define INTEGRATOR_LOCAL_TOLERANCE_FACTOR 1e-2
#define INTEGRATOR_SMALLEST_LOCAL_TOLERANCE 1e-15
double integrator_local_tolerance(double rtol);

/* Event messages go here (may be NULL). */
typedef void (*integrator_log_fn)(void *ctx, const char *message);

/* Create an integrator for the model M (which must outlive it and is read at every call, so a
 * model restored by value in place is seen at the next reset). BDF or Adams follows
 * tether_is_stiff(M). Returns NULL and a message on failure. */
tether_integrator *integrator_create(tether_model *M, integrator_log_fn log, void *log_ctx,
                                     char *msg, size_t len);
void integrator_free(tether_integrator *I);

/* (Re)start at time t from the states y: the history is discarded. */
int integrator_reset(tether_integrator *I, double t, const double *y);

/* Integrate from the current time to t_end, handling events. On success returns 0 with
 * *t_reached = t_end and y the states there. On failure returns -1, *t_reached the last time the
 * solution was good, y the states at that time, and a message in integrator_error(I). */
int integrator_advance(tether_integrator *I, double t_end, double *t_reached, double *y);

/* The same, with CVODE's steps bounded by t_stop >= t_end instead of t_end: its steps may pass
 * t_end, and y is its interpolant there (the stepping goes on from where it is at the next call).
 * For outputs between the points where the inputs change (a batch simulation whose inputs follow
 * the time through integrator_set_input); t_stop must not be before t_end. */
int integrator_advance_within(tether_integrator *I, double t_end, double t_stop, double *t_reached, double *y);

/* Inputs that follow the time: `input(ctx, t, M)` sets M's inputs for the time t before every
 * evaluation of the model's equations and event indicators, and before an event's switches (NULL,
 * the default: the inputs stay as the caller set them, e.g. an FMU's importer). */
typedef void (*integrator_input_fn)(void *ctx, double t, tether_model *M);
void integrator_set_input(tether_integrator *I, integrator_input_fn input, void *ctx);

const char *integrator_error(const tether_integrator *I);

/* Work counters since the integrator was created (over all its resets): for benchmarks, logs and
 * the identification engine's work cap. */
typedef struct {
    long steps, rhs_evaluations, events, resets;
} integrator_stats;
void integrator_get_stats(const tether_integrator *I, integrator_stats *s);

#endif
