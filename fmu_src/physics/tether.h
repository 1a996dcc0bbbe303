/* The tether model: the laws of laws.h assembled into one of three rigs, as a hybrid ODE
 * (continuous states, event indicators, discrete modes). Knows nothing of FMI or of the solver.
 *
 * The tether is a mechanical element (elastic or Kawabata law, Bouc-Wen force z or Iwan force H,
 * damper) in series with a creep element (Kelvin cells and slip), all per unit length:
 *   eps = u / L0 = eps_m + eps_c,    T = F(eps_m) + z + c(x) u'   (clamped at 0 when slack)
 * with z = H(eps_m) for the Iwan law (its elements see the strain held at zero while slack).
 * u is the elongation, eps_m the mechanical strain, eps_c the creep strain, x the displacement
 * that the damping and the Bouc-Wen sign terms see (the payload's displacement from balance in
 * the payload rig, the elongation in the others). The damper acts on the total elongation rate.
 *
 * Rigs:
 *   element  u, u' are inputs; T is the output (a force element between two bodies)
 *   payload  M_eff x'' = M_w g + f(t) - T, u = u_bal + x, u_bal the balance stretch of the elastic
 *            law under M_w g (a mass hanging on the tether). Without line density w, M_eff = M_w = m;
 *            with it, M_w = m + w L0 / 2 (the generalised force of the line's weight) and M_eff the
 *            first-mode effective mass of the line with its end mass (payload_effective_mass)
 *   load     the applied tension T(t) >= 0 is the input; the test is slow, so inertia and damping
 *            play no part: the mechanical strain follows T = F(eps_m) + z quasi-statically.
 *            Without Bouc-Wen the static law is inverted on its branch and the strain relaxes to
 *            the strain that carries the load one tracking time ahead,
 *            eps_m' = (eps*(T + tau T') - eps_m) / tau (exact at every hold, no lag on a ramp,
 *            bounded where a Kawabata branch starts flat; with Iwan, eps* solves F + H = T on the
 *            current branch); with Bouc-Wen it follows the tangent,
 *            eps_m' = (T' + (T - F - z) / tau) / (dF/deps_m + dz/deps_m).
 *            T' comes from the input's derivatives; tau = TETHER_LOAD_TRACKING_TIME.
 */
#ifndef KT_PHYSICS_TETHER_H
#define KT_PHYSICS_TETHER_H

#include <stddef.h>

#include "physics/laws.h"
#include "physics/params.h"

/* continuous states, in the order of modelDescription.xml's ModelStructure/Derivatives */
enum {
    ST_DISPLACEMENT,
    ST_VELOCITY,
    ST_LOAD_ELONGATION,
    ST_HYSTERETIC_FORCE,
    ST_CREEP_1,
    ST_CREEP_2,
    ST_CREEP_3,
    ST_SLIP,
    ST_CAPACITY,
    TETHER_NUMBER_OF_STATES
};

/* event indicators */
enum {
    EV_SLACK_STRAIN,   /* mechanical strain crosses zero (slack entry/exit) */
    EV_SLACK_TENSION,  /* the unclamped tension crosses zero (slack entry/exit) */
    EV_KAWABATA_RATE,  /* the strain rate changes sign (Kawabata or Iwan reversal) */
    EV_KAWABATA_TARGET,/* the branch reaches the turning point it runs to (Kawabata rejoin) */
    TETHER_NUMBER_OF_EVENT_INDICATORS
};

/* Discrete state: everything besides the continuous states that the model needs to go on. Plain
 * values only (no pointers), so a model is saved and restored by value. */
typedef struct {
    int taut;                 /* 1 while the tether carries tension (slack on) */
    kawabata_memory kawabata; /* reversal memory */
    iwan_memory iwan;         /* the Iwan elements' spring strains at the last reversal */
    double balance_elongation;/* u_bal, payload rig */
    /* payload rig, computed once at initialisation (with L0 then): M_w, whose weight M_w g the
     * balance carries, and M_eff, the mass the payload's acceleration sees (0 in the other rigs) */
    double carried_mass, effective_mass;
    /* payload rig: the payload's angular frequency at the balance (the amplitude damping's clock;
     * 0 in the other rigs), computed once at initialisation */
    double swing_rate;
    int warned_rising_limit;  /* the cubic was reported outside its rising range */
    /* the elastic law's rising range [compression_limit, rising_limit], computed once at
     * initialisation (with a power term it takes a search, and the load rig asks at every step) */
    double rising_limit, compression_limit;
} tether_discrete;

typedef struct {
    tether_params p;
    tether_inputs in;
    tether_discrete d;
} tether_model;

/* Everything an observer may want at one instant; field names are modelDescription.xml's. */
typedef struct {
    double tension, strain, elongation, total_elongation, displacement, velocity;
    double load_elongation, hysteretic_force, creep_strain_1, creep_strain_2, creep_strain_3;
    double slip_strain, slip_capacity;
    double der_displacement, der_velocity, der_load_elongation, der_hysteretic_force;
    double der_creep_strain_1, der_creep_strain_2, der_creep_strain_3, der_slip_strain;
    double der_slip_capacity;
    double balance_elongation, creep_total, effective_mass;
    int is_slack;
    /* diagnostics */
    double mechanical_strain, raw_tension;
} tether_outputs;

/* Thresholds that give the slack and reversal switches a tiny hysteresis band, so that an event
 * located by root finding is never ambiguous and a switch cannot chatter. The reversal band is a
 * strain rate [1/s]: far above the rounding noise of a held strain (rtol eps / tau ~ 1e-9 /s in
 * the load rig), far below any deliberate reversal (a payload reverses ~1e-6 s later than exact). */
#define TETHER_SLACK_STRAIN_BAND 1e-13
#define TETHER_SLACK_TENSION_BAND 1e-12
#define TETHER_REVERSAL_RATE_BAND 1e-7
/* load rig: time constant with which the strain catches up with the load [s] */
#define TETHER_LOAD_TRACKING_TIME 1e-3

/* Check the parameters and inputs; on failure write a message that names the variable, its value
 * and what was expected, and return -1. */
int tether_check(const tether_model *M, char *msg, size_t len);

/* The payload rig's masses with the tether line's density w = p->line_density over the natural
 * length L0 (docs/models.md, "The line's own mass"):
 *   payload_carried_mass    M_w = m + w L0 / 2: the balance carries the weight M_w g (the
 *                           generalised force of the line's weight on the payload's coordinate)
 *   payload_effective_mass  M_eff = w L0 / beta^2, beta tan(beta) = w L0 / m: the first mode of a
 *                           uniform elastic line fixed at its top with the end mass m (m exactly at
 *                           w = 0; m + w L0 / 3 to first order in w L0 / m) */
double payload_carried_mass(const tether_params *p, double L0);
double payload_effective_mass(const tether_params *p, double L0);

/* Compute the balance stretch, the initial states y and the initial discrete state. */
int tether_initialize(tether_model *M, double t0, double *y, char *msg, size_t len);

void tether_derivatives(const tether_model *M, double t, const double *y, double *ydot);
void tether_event_indicators(const tether_model *M, double t, const double *y, double *g);

/* Update the discrete state at an event (or after inputs changed). Returns the number of switches
 * made; describes them in msg (for event logging). Idempotent: a second call changes nothing. */
int tether_event_update(tether_model *M, double t, const double *y, char *msg, size_t len);

void tether_compute_outputs(const tether_model *M, double t, const double *y, tether_outputs *out);

/* Nominal magnitude of each state (absolute tolerances are rtol times these). */
void tether_nominals(const tether_model *M, double *nominal);

/* integrator = auto takes BDF on the payload rig where a dissipative law relaxes this many times
 * faster than the payload swings (a narrow Bouc-Wen loop, a sharp dry friction): Adams's steps
 * would shrink to the relaxation's time scale (docs/models.md, "Integrator") */
#define TETHER_STIFF_RELAXATION 100.0

/* 1 when the problem is stiff (creep time scales, the load rig's relaxation, a dissipative law far
 * faster than the swing: TETHER_STIFF_RELAXATION): use BDF. Reads what tether_initialize derived. */
int tether_is_stiff(const tether_model *M);

/* 1 the first time the cubic law is evaluated beyond its rising range (on either side); writes a
 * warning. */
int tether_check_range(tether_model *M, double t, const double *y, char *msg, size_t len);

/* 1 when the states have left any physical range (|strain| beyond TETHER_RUNAWAY_STRAIN): the
 * integration stops at once rather than grinding on; writes why. */
#define TETHER_RUNAWAY_STRAIN 1.0
int tether_runaway(const tether_model *M, double t, const double *y, char *msg, size_t len);

#endif
