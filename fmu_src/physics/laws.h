/* Constitutive laws of a braided Kevlar tether, in the paper's terms.
 *
 * B. Wang, H. Li, J. Zhang, "Experimental investigations on nonlinear mechanical behaviors of
 * Kevlar tether", J. Engineered Fibers and Fabrics 18 (2023). Each law is a pure function of its
 * parameters and arguments; none of them knows about rigs, solvers or FMI.
 */
#ifndef KT_PHYSICS_LAWS_H
#define KT_PHYSICS_LAWS_H

#include "physics/params.h"

/* ---- elastic law (paper: nonlinear stiffness) -------------------------------------------- */
/* Tension of the elastic law at strain eps, not clamped: linear EA eps, or the cubic
 * a1 eps + a2 eps^2 + a3 eps^3 (the same law for every length) plus the power term
 * pow_F sgn(eps) |eps / pow_eps|^pow_n (0 unless pow_F > 0), or the exponential
 * exp_F (exp(eps / exp_eps) - 1) (a stiffness exp_F / exp_eps at eps = 0 that grows with strain),
 * or the bilinear toe_EA eps + (EA - toe_EA) toe_width (softplus((eps - toe_eps) / toe_width) -
 * softplus(-toe_eps / toe_width)) (a toe of stiffness toe_EA, then EA beyond the strain toe_eps). */
double elastic_tension(const tether_params *p, double eps);
/* dF/deps of the elastic law. */
double elastic_stiffness(const tether_params *p, double eps);
/* Largest strain up to which the law keeps rising (dF/deps > 0); HUGE_VAL if it always rises. */
double elastic_rising_limit(const tether_params *p);
/* Smallest (compressive) strain down to which the law keeps rising; -HUGE_VAL if it always rises. */
double elastic_compression_limit(const tether_params *p);
/* Strain at which the elastic law carries the tension T (T >= 0, on the rising part up to
 * rising_limit, the law's elastic_rising_limit: computed once by the caller, for it takes a search
 * with the power term). Returns 0 on success, -1 if T exceeds what the law can carry. */
int elastic_strain_below(const tether_params *p, double T, double rising_limit, double *eps);

/* ---- damping (paper: dynamical property) -------------------------------------------------- */
/* Damping coefficient: c0 (viscous), c(x) = c0 + c1 |x| + c2 x^2 + table(|x|) + c_drag |v|
 * + c_coulomb tanh(v / coulomb_v) / v (displacement-dependent, with an optional velocity-quadratic
 * drag and an optional Coulomb friction force), or c0 + c_coulomb tanh(v / coulomb_v) / v
 * (coulomb: viscous plus dry friction alone), or the displacement law's c(.) at the amplitude
 * A = sqrt(x^2 + (v / swing_rate)^2) in the place of |x| (amplitude; |x| where swing_rate is 0);
 * v is the elongation rate, swing_rate the payload's angular frequency at its balance. */
double damping_coefficient(const tether_params *p, double x, double v, double swing_rate);

/* ---- Kawabata loading/unloading hysteresis ------------------------------------------------ */
#define KAWABATA_MAX_REVERSALS 64
/* a minor loop's branch is at most this many times as stiff as the outer unloading branch's start
 * (kawabata.c); a build may set it (a huge value switches the cap off, to measure without it) */
#ifndef KAWABATA_STIFFNESS_CAP
#define KAWABATA_STIFFNESS_CAP 10.0
#endif
/* Reversal memory: the turning points R_1..R_n in order. R_1 is the largest strain reached on the
 * virgin loading curve; odd points start unloading branches, even points start reloading
 * branches. The current branch runs from R_n towards R_{n-1} (or, for n = 1, towards the residual
 * strain eps_1 = kaw_residual * eps(R_1) at zero tension). A branch that reaches its target is
 * removed with its start (Masing-type rule), so minor loops close and tension stays continuous. */
typedef struct {
    int n;          /* number of stored reversal points */
    int direction;  /* +1 loading, -1 unloading */
    double eps[KAWABATA_MAX_REVERSALS];
    double F[KAWABATA_MAX_REVERSALS];
} kawabata_memory;

double kawabata_loading_exponent(const tether_params *p);   /* 2/LT - 1 */
double kawabata_unloading_exponent(const tether_params *p); /* 2 (1 - r) / (RT LT) - 1 */
double kawabata_virgin_tension(const tether_params *p, double eps);
double kawabata_tension(const tether_params *p, const kawabata_memory *mem, double eps);
/* dF/deps of the current branch */
double kawabata_stiffness(const tether_params *p, const kawabata_memory *mem, double eps);
/* The strain at which the current branch carries tension F (closed form; clamped to the branch's
 * start where F lies on the far side of it, and continued past its end). */
double kawabata_strain_at(const tether_params *p, const kawabata_memory *mem, double F);
void kawabata_reset(kawabata_memory *mem);
/* Reverse the direction at the point (eps, F) of the current branch (pushes a turning point). */
void kawabata_reverse(const tether_params *p, kawabata_memory *mem, double eps, double F);
/* The strain the current branch runs to, where it rejoins an older branch; 0 if none. */
int kawabata_target(const kawabata_memory *mem, double *eps_target);
/* The current branch reached its target: remove it and its start. */
void kawabata_rejoin(kawabata_memory *mem);

/* ---- Bouc-Wen hysteretic force ------------------------------------------------------------ */
/* dz/dt of the generalized Bouc-Wen law (Song and Der Kiureghian 2006):
 *   z' = x' (A - |z|^n psi),
 *   psi = gamma + beta sgn(x' z) + b2 sgn(x x') + b3 sgn(x z) + b4 sgn(x') + b5 sgn(z) + b6 sgn(x)
 * The classic law z' = A x' - beta |x'| |z|^(n-1) z - gamma x' |z|^n is b2..b6 = 0.
 * The force scale is fixed to 1 (z is the hysteretic force in newtons), which removes the
 * redundancy among (A, beta, gamma, scale). */
double boucwen_rate(const tether_params *p, double x, double xdot, double z);
/* The displacement [m] over which z relaxes onto its bound |z|^n = A / psi, psi the largest
 * |gamma| + |beta| + |b2| + ... + |b6| can make it: 1 / (n psi z_u^(n-1)), z_u = (A / psi)^(1/n);
 * 1 / psi for the classic n = 1. A loop this narrow is dry friction; INFINITY where z has no bound. */
double boucwen_saturation_length(const tether_params *p);
/* z of the classic law with n = 1 (dz/dx = A - |z| (gamma + beta sgn(dx z))) along a prescribed
 * displacement path x[0..n-1], starting from z = 0: between two samples the sign of z and of dx
 * are fixed, so the law is linear in x and is integrated exactly (z[k] is z at x[k]). periodic:
 * the path is closed (x[n-1] -> x[0]) and is run twice, the second pass kept. A runaway (the
 * law hardening without bound) stops growing at |z| = 1e12. Used to estimate (A, beta, gamma)
 * from a measured path by equation error. */
void boucwen_path(double A, double beta, double gamma, const double *x, int n, int periodic, double *z);

/* ---- Iwan hysteresis (inter-fibre friction; ours: the paper fits Bouc-Wen) ---------------- */
/* Parallel Jenkins elements (spring k_i [N] in series with a slider that slips at the spring
 * strain eps_i), in parallel with the elastic law; elements with k_i = 0 are absent. */
#define IWAN_ELEMENTS 16
typedef struct {
    int direction;            /* +1 loading, -1 unloading */
    double eps_ref;           /* strain of the last turning point (or where the bank was unloaded) */
    double q[IWAN_ELEMENTS];  /* spring strain of each element at eps_ref */
} iwan_memory;

void iwan_elements(const tether_params *p, double k[IWAN_ELEMENTS], double slip[IWAN_ELEMENTS]);
/* all springs unloaded at the strain eps_unloaded, loading */
void iwan_reset(iwan_memory *mem, double eps_unloaded);
/* force of the bank at strain eps, reached monotonically from the last turning point */
double iwan_force(const tether_params *p, const iwan_memory *mem, double eps);
/* dH/deps in the current direction */
double iwan_stiffness(const tether_params *p, const iwan_memory *mem, double eps);
/* move monotonically to eps and take it as the new reference (the direction is kept) */
void iwan_advance(const tether_params *p, iwan_memory *mem, double eps);
/* a turning point at eps: advance to it and reverse the direction */
void iwan_reverse(const tether_params *p, iwan_memory *mem, double eps);

/* ---- creep (paper: three stages; the law is ours) ----------------------------------------- */
#define CREEP_KELVIN_CELLS 3
typedef struct {
    double kelvin[CREEP_KELVIN_CELLS]; /* recoverable strain of each Kelvin cell */
    double slip;                       /* unrecoverable (slip) strain */
    double capacity;                   /* clearance strain available to slip */
} creep_state;
/* Rates of the creep strains under tension T >= 0: the Kelvin cells, and the slip with its
 * clearance (creep_law = kelvin_slip) or the primary creep (creep_law = primary: its strain in
 * `slip`, `capacity` unused, rate 0). */
void creep_rates(const tether_params *p, double T, const creep_state *s, creep_state *rate);
/* Load activation of the slip, w(T) = T^k / (T^k + T_half^k). */
double creep_slip_activation(const tether_params *p, double T);
/* Rate of the primary creep strain eps_p >= 0 under tension T, strain hardening:
 *   eps_p' = (C / tau) (1 + n eps_p / C)^((n - 1)/n),  C = primary_J T   (n > 0)
 *   eps_p' = (C / tau) exp(-eps_p / C)                                  (n = 0)
 * which under a constant T integrates to eps_p = (C / n)((1 + t/tau)^n - 1) (C ln(1 + t/tau) at
 * n = 0): Findley's power of time beyond tau, regular at t = 0. 0 for T <= 0 (no recovery). */
double creep_primary_rate(const tether_params *p, double T, double eps_p);
/* The creep state of a tether free of creep on which the tension T >= 0 has been held for the time
 * age >= 0 (a preload hung before a record starts): each Kelvin cell at J_k T (1 - exp(-age/tau_k)),
 * the primary creep at (C / n)((1 + age/tau)^n - 1), both closed forms; the slip and its clearance
 * integrated under T (classical Runge-Kutta, each step within the slip's own time scales, until
 * age or until what is left to happen is below 1e-15). Returns 0, or -1 where the slip would take
 * more than CREEP_HOLD_MAX_STEPS steps. */
#define CREEP_HOLD_MAX_STEPS 10000000L
int creep_after_hold(const tether_params *p, double T, double age, creep_state *s);

#endif
