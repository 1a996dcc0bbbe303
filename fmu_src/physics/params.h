/* Parameters, switches and inputs of the tether model.
 *
 * Field names are the variable names of modelDescription.xml: the FMI layer maps each variable
 * onto the field of the same name, so the two cannot drift apart without a compile error. */
#ifndef KT_PHYSICS_PARAMS_H
#define KT_PHYSICS_PARAMS_H

typedef enum { RIG_ELEMENT = 1, RIG_PAYLOAD = 2, RIG_LOAD = 3 } tether_rig;
typedef enum { STIFFNESS_LINEAR = 1, STIFFNESS_CUBIC = 2, STIFFNESS_EXPONENTIAL = 3, STIFFNESS_BILINEAR = 4 } stiffness_law;
typedef enum { DAMPING_VISCOUS = 1, DAMPING_DISPLACEMENT = 2, DAMPING_COULOMB = 3, DAMPING_AMPLITUDE = 4 } damping_law;
typedef enum { HYSTERESIS_NONE = 1, HYSTERESIS_KAWABATA = 2, HYSTERESIS_BOUCWEN = 3, HYSTERESIS_IWAN = 4 } hysteresis_law;
typedef enum { CREEP_KELVIN_SLIP = 1, CREEP_PRIMARY = 2 } creep_law_choice;
typedef enum { INTEGRATOR_AUTO = 1, INTEGRATOR_BDF = 2, INTEGRATOR_ADAMS = 3 } integrator_choice;

typedef struct {
    /* structural switches */
    int rig, stiffness, damping, hysteresis, creep, slack, integrator, creep_law;
    double rtol;
    /* payload */
    double m, g, x0, v0;
    /* payload rig, Iwan bank: how far beyond the span [-|x0|, |x0|] the motion last reversed
     * before t0 (0: displaced monotonically from the balance; tether.c: last_reversal) */
    double last_reversal_beyond;
    /* payload rig: the tether line's own mass per length [kg/m], its share of the weight and of
     * the inertia (tether.h: payload_carried_mass, payload_effective_mass) */
    double line_density;
    /* elastic law: linear EA, or the cubic a1..a3 plus a power term pow_F |eps/pow_eps|^pow_n, or
     * the exponential exp_F (exp(eps/exp_eps) - 1), or the bilinear: a toe of stiffness toe_EA up
     * to the strain toe_eps, then EA, the corner rounded over toe_width */
    double EA, a1, a2, a3;
    double pow_F, pow_eps, pow_n;
    double exp_F, exp_eps;
    double toe_EA, toe_eps, toe_width;
    /* damping: c(x) = c0 + c1 |x| + c2 x^2 + a table over |x| (knots c_table_dx apart; the
     * amplitude law: the same c(.) of the swing's amplitude in the place of |x|),
     * plus c_drag |v| (velocity-quadratic drag) and a Coulomb (dry-friction) force
     * c_coulomb tanh(v / coulomb_v) */
    double c0, c1, c2;
    double c_table_dx, c_table_1, c_table_2, c_table_3, c_table_4, c_table_5, c_table_6;
    double c_drag;
    double c_coulomb, coulomb_v;
    /* Kawabata */
    double kaw_LT, kaw_RT, kaw_eps_ref, kaw_F_ref, kaw_residual;
    /* Bouc-Wen */
    double bw_A, bw_beta, bw_gamma, bw_n, bw_b2, bw_b3, bw_b4, bw_b5, bw_b6, z0;
    /* Iwan: element stiffnesses [N] and slip strains */
    double iw_k1, iw_k2, iw_k3, iw_k4, iw_k5, iw_k6, iw_k7, iw_k8;
    double iw_k9, iw_k10, iw_k11, iw_k12, iw_k13, iw_k14, iw_k15, iw_k16;
    double iw_eps1, iw_eps2, iw_eps3, iw_eps4, iw_eps5, iw_eps6, iw_eps7, iw_eps8;
    double iw_eps9, iw_eps10, iw_eps11, iw_eps12, iw_eps13, iw_eps14, iw_eps15, iw_eps16;
    /* creep: recoverable Kelvin cells and unrecoverable slip */
    double creep_J1, creep_tau1, creep_J2, creep_tau2, creep_J3, creep_tau3;
    double slip_capacity0, slip_rate, slip_knee, slip_load_half, slip_load_exponent;
    double slip_regen_tau, slip_limit;
    /* primary creep (creep_law = primary, in the slip's place): eps_p = (J T / n)((1 + t/tau)^n - 1)
     * under a constant T (J T ln(1 + t/tau) at n = 0), as a strain-hardening state equation */
    double primary_J, primary_tau, primary_n;
    /* load rig, creep: how long the first load had hung on a tether free of creep before the record
     * started (0: the record starts free of creep; laws.h: creep_after_hold) */
    double creep_preload_age;
    /* load rig, Iwan: the load at which the elements were last unloaded before the record, from where
     * the tether was brought monotonically to the first load (0: a virgin tether) */
    double iwan_relaxed_load;
} tether_params;

/* Inputs. force and load may carry time derivatives up to third order (input interpolation): from
 * t_ref on they are the polynomial force + d1 s + d2 s^2/2 + d3 s^3/6, s = t - t_ref, likewise
 * load; a cubic spline through sampled data is then reproduced exactly. */
#define TETHER_INPUT_DERIVATIVE_ORDER 3
typedef struct {
    double L0, elongation, elongation_rate, force, load;
    double force_der[TETHER_INPUT_DERIVATIVE_ORDER], load_der[TETHER_INPUT_DERIVATIVE_ORDER];
    double t_ref;
} tether_inputs;

#endif
