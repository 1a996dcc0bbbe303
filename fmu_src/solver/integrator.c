/* CVODE (SUNDIALS 6) wrapper. See integrator.h. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include "solver/integrator.h"

#define N_STATES TETHER_NUMBER_OF_STATES
#define N_EVENTS TETHER_NUMBER_OF_EVENT_INDICATORS
/* One advance (one communication step) has a bounded cost, whatever the model does: at most this
 * many events (a run that needs more is chattering; a storm of this many costs well under a second,
 * docs/robustness.md) ... */
#define MAX_EVENTS_PER_ADVANCE 5000L
/* ... and at most this many CVODE steps in all, across the restarts at events (a stuck, runaway or
 * chattering run) */
#define INTEGRATOR_MAX_STEPS 200000L

struct tether_integrator {
    tether_model *M;
    SUNContext ctx;
    void *cvode;
    N_Vector y, abstol;
    SUNMatrix A;
    SUNLinearSolver LS;
    SUNNonlinearSolver NLS;
    int stiff;
    double t;
    integrator_log_fn log;
    void *log_ctx;
    integrator_input_fn input; /* NULL: the model's inputs stay as set */
    void *input_ctx;
    long events, resets;
    long steps_before, rhs_before; /* CVODE's counts of the runs before its last re-initialisation */
    long runaway_refusals; /* rhs calls refused as a runaway within this advance */
    char runaway[512];     /* why the last of them was refused */
    char error[512];
};

/* A state beyond the runaway bounds refuses the rhs call as recoverable: it is often a trial of a
 * long step (the predictor of a step across a long hold extrapolates far past any tether's strain),
 * and CVODE retries it shorter. After this many refused calls CVODE is stopped: a run that really
 * runs away would otherwise creep towards the bound in ever smaller steps (up to its whole step
 * budget, ~1 s) */
#define RUNAWAY_REFUSALS_TO_STOP 50

double integrator_local_tolerance(double rtol)
{
    const double local = rtol * INTEGRATOR_LOCAL_TOLERANCE_FACTOR;
    return local > INTEGRATOR_SMALLEST_LOCAL_TOLERANCE ? local : INTEGRATOR_SMALLEST_LOCAL_TOLERANCE;
}

static int rhs(realtype t, N_Vector y, N_Vector ydot, void *user)
{
    tether_integrator *I = (tether_integrator *)user;
    if (I->input) I->input(I->input_ctx, t, I->M);
    if (tether_runaway(I->M, t, NV_DATA_S(y), I->runaway, sizeof I->runaway)) {
        I->runaway_refusals += 1;
        return I->runaway_refusals >= RUNAWAY_REFUSALS_TO_STOP ? -1 : 1; /* 1: CVODE retries a shorter step */
    }
    tether_derivatives(I->M, t, NV_DATA_S(y), NV_DATA_S(ydot));
    for (int i = 0; i < N_STATES; ++i)
        if (!isfinite(NV_Ith_S(ydot, i))) return 1; /* recoverable: CVODE retries a smaller step */
    return 0;
}

static int roots(realtype t, N_Vector y, realtype *g, void *user)
{
    const tether_integrator *I = (const tether_integrator *)user;
    if (I->input) I->input(I->input_ctx, t, I->M);
    tether_event_indicators(I->M, t, NV_DATA_S(y), g);
    return I->runaway_refusals >= RUNAWAY_REFUSALS_TO_STOP ? -1 : 0; /* -1: CVode returns at once */
}

static void on_cvode_error(int code, const char *module, const char *function, char *msg, void *user)
{
    tether_integrator *I = (tether_integrator *)user;
    if (I->error[0]) return; /* keep the first, most specific reason (e.g. a runaway) */
    snprintf(I->error, sizeof I->error, "%s (%s, flag %d): %s", function, module, code, msg);
}

tether_integrator *integrator_create(tether_model *M, integrator_log_fn log, void *log_ctx,
                                     char *msg, size_t len)
{
    tether_integrator *I = (tether_integrator *)calloc(1, sizeof *I);
    if (!I) { snprintf(msg, len, "out of memory"); return NULL; }
    I->M = M;
    I->log = log;
    I->log_ctx = log_ctx;
    I->stiff = tether_is_stiff(M);
    if (SUNContext_Create(NULL, &I->ctx) != 0) goto fail;
    I->y = N_VNew_Serial(N_STATES, I->ctx);
    I->abstol = N_VNew_Serial(N_STATES, I->ctx);
    if (!I->y || !I->abstol) goto fail;
    N_VConst(0.0, I->y);
    I->cvode = CVodeCreate(I->stiff ? CV_BDF : CV_ADAMS, I->ctx);
    if (!I->cvode) goto fail;
    CVodeSetErrHandlerFn(I->cvode, on_cvode_error, I);
    if (CVodeInit(I->cvode, rhs, 0.0, I->y) != CV_SUCCESS) goto fail;
    double nominal[N_STATES];
    tether_nominals(M, nominal);
    const double local_rtol = integrator_local_tolerance(M->p.rtol);
    for (int i = 0; i < N_STATES; ++i) NV_Ith_S(I->abstol, i) = local_rtol * nominal[i];
    if (CVodeSVtolerances(I->cvode, local_rtol, I->abstol) != CV_SUCCESS) goto fail;
    if (CVodeSetUserData(I->cvode, I) != CV_SUCCESS) goto fail;
    if (CVodeRootInit(I->cvode, N_EVENTS, roots) != CV_SUCCESS) goto fail;
    if (I->stiff) {
        I->A = SUNDenseMatrix(N_STATES, N_STATES, I->ctx);
        I->LS = SUNLinSol_Dense(I->y, I->A, I->ctx);
        if (!I->A || !I->LS || CVodeSetLinearSolver(I->cvode, I->LS, I->A) != CV_SUCCESS) goto fail;
    } else {
        I->NLS = SUNNonlinSol_FixedPoint(I->y, 0, I->ctx);
        if (!I->NLS || CVodeSetNonlinearSolver(I->cvode, I->NLS) != CV_SUCCESS) goto fail;
    }
    CVodeSetMaxNumSteps(I->cvode, INTEGRATOR_MAX_STEPS);
    CVodeSetMaxHnilWarns(I->cvode, -1);
    return I;
fail:
    snprintf(msg, len, "could not set up CVODE%s%s", I->error[0] ? ": " : "", I->error);
    integrator_free(I);
    return NULL;
}

void integrator_free(tether_integrator *I)
{
    if (!I) return;
    if (I->cvode) CVodeFree(&I->cvode);
    if (I->LS) SUNLinSolFree(I->LS);
    if (I->NLS) SUNNonlinSolFree(I->NLS);
    if (I->A) SUNMatDestroy(I->A);
    if (I->y) N_VDestroy(I->y);
    if (I->abstol) N_VDestroy(I->abstol);
    if (I->ctx) SUNContext_Free(&I->ctx);
    free(I);
}

/* CVODE's step and right-hand-side counts since its last (re-)initialisation */
static void cvode_counts(const tether_integrator *I, long *steps, long *rhs_evaluations)
{
    long int nst = 0, nfe = 0;
    CVodeGetNumSteps(I->cvode, &nst);
    CVodeGetNumRhsEvals(I->cvode, &nfe);
    *steps = nst;
    *rhs_evaluations = nfe;
}

/* CVodeReInit zeroes CVODE's counters: keep what they held */
static void bank_counts(tether_integrator *I)
{
    long nst, nfe;
    cvode_counts(I, &nst, &nfe);
    I->steps_before += nst;
    I->rhs_before += nfe;
}

int integrator_reset(tether_integrator *I, double t, const double *y)
{
    memcpy(NV_DATA_S(I->y), y, sizeof(double) * N_STATES);
    I->t = t;
    I->resets += 1;
    bank_counts(I);
    if (CVodeReInit(I->cvode, t, I->y) != CV_SUCCESS) return -1;
    return 0;
}

void integrator_set_input(tether_integrator *I, integrator_input_fn input, void *ctx)
{
    I->input = input;
    I->input_ctx = ctx;
}

int integrator_advance(tether_integrator *I, double t_end, double *t_reached, double *y)
{
    return integrator_advance_within(I, t_end, t_end, t_reached, y);
}

int integrator_advance_within(tether_integrator *I, double t_end, double t_stop, double *t_reached, double *y)
{
    long events = 0, steps = 0;
    I->error[0] = '\0';
    I->runaway_refusals = 0;
    while (I->t < t_end) {
        if (steps >= INTEGRATOR_MAX_STEPS) {
            snprintf(I->error, sizeof I->error, "%ld solver steps and %ld events within one step, stopped at "
                     "t = %.17g s before t = %.17g s (a stuck, runaway or chattering run)", steps, events, I->t, t_end);
            break;
        }
        realtype tret = I->t;
        CVodeSetStopTime(I->cvode, t_stop);
        long before = 0, after = 0;
        CVodeGetNumSteps(I->cvode, &before);
        CVodeSetMaxNumSteps(I->cvode, INTEGRATOR_MAX_STEPS - steps); /* what is left of the budget, >= 1 */
        const int flag = CVode(I->cvode, t_end, I->y, &tret, CV_NORMAL);
        CVodeGetNumSteps(I->cvode, &after);
        steps += after - before;
        if (flag == CV_TOO_MUCH_WORK && I->runaway_refusals == 0) { /* a runaway is the more specific reason */
            snprintf(I->error, sizeof I->error, "%ld solver steps and %ld events within one step, stopped at "
                     "t = %.17g s before t = %.17g s (a stuck, runaway or chattering run)", steps, events, (double)tret, t_end);
        }
        if (flag == CV_ROOT_RETURN) {
            I->t = tret;
            char note[1024];
            if (I->input) I->input(I->input_ctx, tret, I->M);
            const int switches = tether_event_update(I->M, tret, NV_DATA_S(I->y), note, sizeof note);
            if (switches > 0) {
                if (I->log) I->log(I->log_ctx, note);
                I->events += switches;
                if (++events > MAX_EVENTS_PER_ADVANCE) {
                    snprintf(I->error, sizeof I->error, "more than %ld events within one step, stopped at t = %.17g s "
                             "before t = %.17g s (chattering)", MAX_EVENTS_PER_ADVANCE, (double)tret, t_end);
                    break;
                }
                bank_counts(I);
                if (CVodeReInit(I->cvode, tret, I->y) != CV_SUCCESS) break;
                I->resets += 1;
            }
            continue;
        }
        if (flag < 0) {
            if (I->runaway_refusals > 0) /* the runaway is the more specific reason */
                snprintf(I->error, sizeof I->error, "%s", I->runaway);
            else if (!I->error[0])
                snprintf(I->error, sizeof I->error, "CVode failed with flag %d", flag);
            /* the last good point: CVODE's current internal time and solution */
            realtype tcur = I->t;
            if (CVodeGetCurrentTime(I->cvode, &tcur) == CV_SUCCESS && tcur > I->t &&
                CVodeGetDky(I->cvode, tcur, 0, I->y) == CV_SUCCESS) {
                I->t = tcur;
            }
            memcpy(y, NV_DATA_S(I->y), sizeof(double) * N_STATES);
            *t_reached = I->t;
            return -1;
        }
        I->t = t_end; /* CV_SUCCESS (at or interpolated back to t_end) or CV_TSTOP_RETURN: tret == t_end */
    }
    memcpy(y, NV_DATA_S(I->y), sizeof(double) * N_STATES);
    *t_reached = I->t;
    return I->error[0] ? -1 : 0;
}

const char *integrator_error(const tether_integrator *I) { return I->error; }

void integrator_get_stats(const tether_integrator *I, integrator_stats *s)
{
    long nst, nfe;
    cvode_counts(I, &nst, &nfe);
    s->steps = I->steps_before + nst;
    s->rhs_evaluations = I->rhs_before + nfe;
    s->events = I->events;
    s->resets = I->resets;
}
