/* The tether model: rig equations, event indicators and discrete switches. See tether.h. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "physics/tether.h"

/* quantities that follow from the states at one instant */
typedef struct {
    double L0, u, udot, x, eps_c, eps_m, F, z, c, T_raw, T, eps_m_rate, eps_m_rate_load;
    double eps_h, eps_h_rate; /* the strain the hysteresis sees (Kawabata, Iwan) and its rate */
    creep_state creep, creep_rate;
} tether_instant;

static double input_polynomial(double value, const double *der, double s)
{
    return value + s * (der[0] + s * (der[1] / 2.0 + s * der[2] / 6.0));
}

static double input_polynomial_rate(const double *der, double s)
{
    return der[0] + s * (der[1] + s * der[2] / 2.0);
}

static double input_force(const tether_model *M, double t)
{
    return input_polynomial(M->in.force, M->in.force_der, t - M->in.t_ref);
}

/* a hanging load pulls; it never pushes (an interpolating polynomial may dip below zero) */
static double input_load(const tether_model *M, double t)
{
    const double T = input_polynomial(M->in.load, M->in.load_der, t - M->in.t_ref);
    return T > 0.0 ? T : 0.0;
}

static double input_load_rate(const tether_model *M, double t)
{
    if (input_polynomial(M->in.load, M->in.load_der, t - M->in.t_ref) <= 0.0) return 0.0;
    return input_polynomial_rate(M->in.load_der, t - M->in.t_ref);
}

/* ---- the payload rig's line: its share of the weight and of the inertia ---------------------- */

double payload_carried_mass(const tether_params *p, double L0)
{
    return p->m + 0.5 * p->line_density * L0;
}

/* beta in (0, pi/2) with beta tan(beta) = mu (mu > 0): the first mode of a uniform elastic line
 * fixed at its top with an end mass, mu = line mass / end mass. f(beta) = beta sin(beta) -
 * mu cos(beta) rises from -mu at 0 to pi/2 at pi/2: Newton kept inside a shrinking bracket. */
static double first_mode_beta(double mu)
{
    const double half_pi = 2.0 * atan(1.0);
    if (!(mu < 1e17)) return half_pi; /* pi/2 - beta ~ pi / (2 mu), below the rounding of pi/2 */
    double lo = 0.0, hi = half_pi;
    double beta = mu < 1.0 ? sqrt(mu) : half_pi * mu / (1.0 + mu);
    for (int it = 0; it < 200 && hi - lo > 4e-16 * hi; ++it) {
        const double s = sin(beta), c = cos(beta);
        const double f = beta * s - mu * c;
        if (f == 0.0) break;
        if (f < 0.0) lo = beta; else hi = beta;
        double next = beta - f / ((1.0 + mu) * s + beta * c);
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        const double moved = fabs(next - beta);
        beta = next;
        if (moved <= 1e-16 * beta) break;
    }
    return beta;
}

double payload_effective_mass(const tether_params *p, double L0)
{
    const double line = p->line_density * L0, mu = line / p->m;
    if (line == 0.0) return p->m;
    if (mu < 1e-3) /* m mu / beta^2 as a series; its next term, 11 mu^4 / 14175, is below 1e-15 */
        return p->m * (1.0 + mu * (1.0 / 3.0 + mu * (1.0 / 45.0 - mu / 189.0)));
    const double beta = first_mode_beta(mu);
    return line / (beta * beta);
}

static int slack_active(const tether_model *M)
{
    return M->p.slack && M->p.rig != RIG_LOAD;
}

static double static_tension(const tether_model *M, double eps_m)
{
    if (M->p.hysteresis == HYSTERESIS_KAWABATA) return kawabata_tension(&M->p, &M->d.kawabata, eps_m);
    return elastic_tension(&M->p, eps_m);
}

/* dF/deps of the static law on the current branch */
static double static_stiffness(const tether_model *M, double eps_m)
{
    if (M->p.hysteresis == HYSTERESIS_KAWABATA) return kawabata_stiffness(&M->p, &M->d.kawabata, eps_m);
    return elastic_stiffness(&M->p, eps_m);
}

/* the strain the Iwan elements see: a slack tether is shortened, not compressed, so its fibres
 * stay at zero strain and the friction between them sees no motion */
static double iwan_strain(const tether_model *M, double eps_m)
{
    return (slack_active(M) && eps_m < 0.0) ? 0.0 : eps_m;
}

/* The strain at which the elastic law and the Iwan elements on their current branch carry T:
 * F(eps) + H(eps) = T, rising in eps on the elastic law's rising part. Safeguarded Newton in a
 * bracket grown from eps_guess. Returns 0, or -1 if no strain up to the rising limit carries T. */
static int iwan_rig_strain_at(const tether_model *M, double T, double eps_guess, double *eps)
{
    const tether_params *p = &M->p;
    const double top = M->d.rising_limit;
#define G(e) (elastic_tension(p, (e)) + iwan_force(p, &M->d.iwan, (e)) - T)
    double lo = eps_guess, hi = eps_guess, step = 1e-6;
    if (lo > top) lo = hi = top;
    if (G(lo) > 0.0) {
        do { lo -= step; step *= 2.0; } while (G(lo) > 0.0 && step < 1e6);
    } else {
        do {
            hi += step; step *= 2.0;
            if (hi >= top) { hi = top; if (G(hi) < 0.0) return -1; break; }
        } while (G(hi) < 0.0 && step < 1e6);
    }
    double e = 0.5 * (lo + hi);
    for (int it = 0; it < 200 && hi - lo > 1e-15 * (1.0 + fabs(e)); ++it) {
        const double g = G(e);
        if (g == 0.0) break;
        if (g > 0.0) hi = e; else lo = e;
        const double K = elastic_stiffness(p, e) + iwan_stiffness(p, &M->d.iwan, e);
        double next = K > 0.0 ? e - g / K : 0.5 * (lo + hi);
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        e = next;
    }
#undef G
    *eps = e;
    return 0;
}

/* a stiffness scale of the static law, to keep the load rig's tracking well posed where the
 * tangent stiffness vanishes (the Kawabata branches at their ends) */
static double stiffness_scale(const tether_model *M)
{
    const tether_params *p = &M->p;
    if (p->hysteresis == HYSTERESIS_KAWABATA) return p->kaw_F_ref / p->kaw_eps_ref;
    if (p->stiffness == STIFFNESS_EXPONENTIAL) return p->exp_F / p->exp_eps;
    if (p->stiffness == STIFFNESS_BILINEAR) return fmin(p->toe_EA, p->EA);
    return p->stiffness == STIFFNESS_LINEAR ? p->EA : p->a1;
}

static void evaluate(const tether_model *M, double t, const double *y, tether_instant *s)
{
    const tether_params *p = &M->p;
    s->L0 = M->in.L0;
    memset(&s->creep, 0, sizeof s->creep);
    memset(&s->creep_rate, 0, sizeof s->creep_rate);
    if (p->creep) {
        s->creep.kelvin[0] = y[ST_CREEP_1];
        s->creep.kelvin[1] = y[ST_CREEP_2];
        s->creep.kelvin[2] = y[ST_CREEP_3];
        s->creep.slip = y[ST_SLIP];
        s->creep.capacity = y[ST_CAPACITY];
    }
    s->eps_c = s->creep.kelvin[0] + s->creep.kelvin[1] + s->creep.kelvin[2] + s->creep.slip;
    switch (p->rig) {
    case RIG_PAYLOAD:
        s->x = y[ST_DISPLACEMENT];
        s->u = M->d.balance_elongation + s->x;
        s->udot = y[ST_VELOCITY];
        break;
    case RIG_LOAD:
        s->u = y[ST_LOAD_ELONGATION];
        s->x = s->u;
        s->udot = 0.0; /* below */
        break;
    default:
        s->u = M->in.elongation;
        s->x = s->u;
        s->udot = M->in.elongation_rate;
        break;
    }
    s->eps_m = s->u / s->L0 - s->eps_c;
    s->F = static_tension(M, s->eps_m);
    s->eps_h = p->hysteresis == HYSTERESIS_IWAN ? iwan_strain(M, s->eps_m) : s->eps_m;
    if (p->hysteresis == HYSTERESIS_BOUCWEN) s->z = y[ST_HYSTERETIC_FORCE];
    else if (p->hysteresis == HYSTERESIS_IWAN) s->z = iwan_force(p, &M->d.iwan, s->eps_h);
    else s->z = 0.0;
    s->c = damping_coefficient(p, s->x, s->udot, M->d.swing_rate);
    if (p->rig == RIG_LOAD) {
        /* quasi-static: the mechanical strain follows T = F(eps_m) + z; see tether.h */
        s->T = input_load(M, t);
        s->T_raw = s->T;
        if (p->hysteresis == HYSTERESIS_BOUCWEN) {
            /* z depends on the path: follow the tangent dF/deps_m + dz/deps_m, feeding the load's
             * rate forward and removing the mismatch with time constant tau */
            const double demand = input_load_rate(M, t) + (s->T - s->F - s->z) / TETHER_LOAD_TRACKING_TIME;
            const double dir = demand >= 0.0 ? 1.0 : -1.0;
            double K = static_stiffness(M, s->eps_m) + s->L0 * boucwen_rate(p, s->x, dir, s->z) / dir;
            const double K_floor = 1e-6 * stiffness_scale(M);
            if (!(K > K_floor)) K = K_floor;
            s->eps_m_rate_load = demand / K;
        } else {
            /* the static law is invertible on its current branch: relax towards the strain that
             * carries the load one tracking time ahead, T + tau T'. Exact at every hold, no lag on
             * a ramp, and bounded where a Kawabata branch starts flat (dF/deps = 0) */
            double ahead = s->T + TETHER_LOAD_TRACKING_TIME * input_load_rate(M, t);
            if (ahead < 0.0) ahead = 0.0;
            double target;
            if (p->hysteresis == HYSTERESIS_KAWABATA) {
                target = kawabata_strain_at(p, &M->d.kawabata, ahead);
            } else if (p->hysteresis == HYSTERESIS_IWAN) {
                if (iwan_rig_strain_at(M, ahead, s->eps_m, &target) != 0) target = M->d.rising_limit;
            } else if (elastic_strain_below(p, ahead, M->d.rising_limit, &target) != 0) {
                target = M->d.rising_limit;
            }
            s->eps_m_rate_load = (target - s->eps_m) / TETHER_LOAD_TRACKING_TIME;
        }
    } else {
        s->T_raw = s->F + s->z + s->c * s->udot;
        s->T = (slack_active(M) && !M->d.taut) ? 0.0 : s->T_raw;
    }
    if (p->creep) creep_rates(p, s->T, &s->creep, &s->creep_rate);
    const double eps_c_rate = s->creep_rate.kelvin[0] + s->creep_rate.kelvin[1] +
                              s->creep_rate.kelvin[2] + s->creep_rate.slip;
    if (p->rig == RIG_LOAD) {
        s->eps_m_rate = s->eps_m_rate_load;
        s->udot = s->L0 * (s->eps_m_rate + eps_c_rate);
    } else {
        s->eps_m_rate = s->udot / s->L0 - eps_c_rate;
    }
    s->eps_h_rate = (p->hysteresis == HYSTERESIS_IWAN && slack_active(M) && s->eps_m < 0.0) ? 0.0 : s->eps_m_rate;
}

int tether_check(const tether_model *M, char *msg, size_t len)
{
    const tether_params *p = &M->p;
#define FAIL(...) do { snprintf(msg, len, __VA_ARGS__); return -1; } while (0)
    if (p->rig < RIG_ELEMENT || p->rig > RIG_LOAD) FAIL("rig = %d: expected 1 (element), 2 (payload) or 3 (load)", p->rig);
    if (p->stiffness < STIFFNESS_LINEAR || p->stiffness > STIFFNESS_BILINEAR) FAIL("stiffness = %d: expected 1 (linear), 2 (cubic), 3 (exponential) or 4 (bilinear)", p->stiffness);
    if (p->damping < DAMPING_VISCOUS || p->damping > DAMPING_AMPLITUDE) FAIL("damping = %d: expected 1 (viscous), 2 (displacement), 3 (coulomb) or 4 (amplitude)", p->damping);
    if (p->hysteresis < HYSTERESIS_NONE || p->hysteresis > HYSTERESIS_IWAN) FAIL("hysteresis = %d: expected 1 (none), 2 (kawabata), 3 (boucwen) or 4 (iwan)", p->hysteresis);
    if (p->creep_law < CREEP_KELVIN_SLIP || p->creep_law > CREEP_PRIMARY) FAIL("creep_law = %d: expected 1 (kelvin_slip) or 2 (primary)", p->creep_law);
    if (p->integrator < INTEGRATOR_AUTO || p->integrator > INTEGRATOR_ADAMS) FAIL("integrator = %d: expected 1 (auto), 2 (bdf) or 3 (adams)", p->integrator);
    if (!(p->rtol >= 1e-14 && p->rtol <= 1e-2)) FAIL("rtol = %g: expected a relative tolerance in [1e-14, 1e-2]", p->rtol);
    if (!(M->in.L0 > 0.0) || !isfinite(M->in.L0)) FAIL("L0 = %g m: the natural length must be positive", M->in.L0);
    if (p->rig == RIG_PAYLOAD && !(p->m > 0.0)) FAIL("m = %g kg: the payload rig needs a positive mass", p->m);
    if (!(p->line_density >= 0.0) || !isfinite(p->line_density))
        FAIL("line_density = %g kg/m: expected the tether line's mass per length, finite and >= 0", p->line_density);
    if (!(p->g >= 0.0)) FAIL("g = %g m/s2: expected g >= 0", p->g);
    if (!(p->creep_preload_age >= 0.0) || !isfinite(p->creep_preload_age))
        FAIL("creep_preload_age = %g s: expected the time the first load had hung before the record, finite and >= 0",
             p->creep_preload_age);
    if (p->creep_preload_age > 0.0 && p->rig != RIG_LOAD)
        FAIL("creep_preload_age = %g s: a preload's creep is a load-rig record's (rig = 3); rig = %d starts free of creep",
             p->creep_preload_age, p->rig);
    if (!(p->iwan_relaxed_load >= 0.0) || !isfinite(p->iwan_relaxed_load))
        FAIL("iwan_relaxed_load = %g N: expected the load at which the Iwan elements were last unloaded, finite and >= 0",
             p->iwan_relaxed_load);
    if (p->iwan_relaxed_load > 0.0 && p->rig != RIG_LOAD)
        FAIL("iwan_relaxed_load = %g N: a load the bank was unloaded at is a load-rig record's (rig = 3); rig = %d "
             "starts its bank as its own initial state says", p->iwan_relaxed_load, p->rig);
    if (!isfinite(p->last_reversal_beyond)) FAIL("last_reversal_beyond = %g m: expected a finite distance", p->last_reversal_beyond);
    if (p->stiffness == STIFFNESS_LINEAR && p->hysteresis != HYSTERESIS_KAWABATA && !(p->EA > 0.0)) FAIL("EA = %g N: the linear law needs EA > 0", p->EA);
    if (p->stiffness == STIFFNESS_BILINEAR && p->hysteresis != HYSTERESIS_KAWABATA) {
        if (!(p->EA > 0.0) || !isfinite(p->EA)) FAIL("EA = %g N: the bilinear law needs EA > 0 (its stiffness beyond the toe)", p->EA);
        if (!(p->toe_EA > 0.0) || !isfinite(p->toe_EA)) FAIL("toe_EA = %g N: the bilinear law needs a toe stiffness toe_EA > 0", p->toe_EA);
        if (!(p->toe_eps > 0.0) || !isfinite(p->toe_eps)) FAIL("toe_eps = %g: the bilinear law's corner strain must be positive", p->toe_eps);
        if (!(p->toe_width > 0.0) || !isfinite(p->toe_width)) FAIL("toe_width = %g: the bilinear law's corner width must be positive", p->toe_width);
    }
    if (p->stiffness == STIFFNESS_CUBIC && p->hysteresis != HYSTERESIS_KAWABATA && !(p->a1 > 0.0)) FAIL("a1 = %g N: the cubic law needs a1 > 0", p->a1);
    if (p->stiffness == STIFFNESS_EXPONENTIAL && p->hysteresis != HYSTERESIS_KAWABATA) {
        if (!(p->exp_F > 0.0) || !isfinite(p->exp_F)) FAIL("exp_F = %g N: the exponential law needs exp_F > 0", p->exp_F);
        if (!(p->exp_eps > 0.0) || !isfinite(p->exp_eps)) FAIL("exp_eps = %g: the exponential law needs a positive strain scale", p->exp_eps);
    }
    if (!(p->pow_F >= 0.0)) FAIL("pow_F = %g N: expected pow_F >= 0", p->pow_F);
    if (!(p->pow_eps > 0.0) || !isfinite(p->pow_eps)) FAIL("pow_eps = %g: the power term's reference strain must be positive", p->pow_eps);
    if (!(p->pow_n >= 1.0 && p->pow_n <= 4.0)) FAIL("pow_n = %g: expected an exponent in [1, 4]", p->pow_n);
    if (!(p->c0 >= 0.0)) FAIL("c0 = %g N.s/m: expected c0 >= 0", p->c0);
    if (!(p->c1 >= 0.0)) FAIL("c1 = %g N.s/m2: expected c1 >= 0", p->c1);
    if (!(p->c2 >= 0.0)) FAIL("c2 = %g N.s/m3: expected c2 >= 0", p->c2);
    if (!(p->c_drag >= 0.0)) FAIL("c_drag = %g kg/m: expected c_drag >= 0", p->c_drag);
    if (!(p->c_coulomb >= 0.0) || !isfinite(p->c_coulomb)) FAIL("c_coulomb = %g N: expected a finite c_coulomb >= 0", p->c_coulomb);
    if (!(p->coulomb_v > 0.0) || !isfinite(p->coulomb_v))
        FAIL("coulomb_v = %g m/s: expected a positive velocity over which the friction force changes sign", p->coulomb_v);
    if (p->hysteresis == HYSTERESIS_KAWABATA) {
        if (!(p->kaw_LT > 0.05 && p->kaw_LT < 1.95)) FAIL("kaw_LT = %g: expected a linearity in (0.05, 1.95)", p->kaw_LT);
        if (!(p->kaw_RT > 0.0 && p->kaw_RT <= 1.0)) FAIL("kaw_RT = %g: expected a resilience in (0, 1]", p->kaw_RT);
        if (!(p->kaw_residual >= 0.0 && p->kaw_residual < 0.95)) FAIL("kaw_residual = %g: expected a fraction in [0, 0.95)", p->kaw_residual);
        if (!(p->kaw_eps_ref > 0.0)) FAIL("kaw_eps_ref = %g: expected a positive strain", p->kaw_eps_ref);
        if (!(p->kaw_F_ref > 0.0)) FAIL("kaw_F_ref = %g N: expected a positive tension", p->kaw_F_ref);
        if (!(kawabata_unloading_exponent(p) > 0.0))
            FAIL("kaw_RT = %g with kaw_LT = %g and kaw_residual = %g give an unloading exponent %g <= 0: "
                 "expected 2 (1 - kaw_residual) > kaw_RT kaw_LT", p->kaw_RT, p->kaw_LT, p->kaw_residual,
                 kawabata_unloading_exponent(p));
    }
    if (p->hysteresis == HYSTERESIS_BOUCWEN && !(p->bw_n > 0.0)) FAIL("bw_n = %g: expected n > 0", p->bw_n);
    if (p->hysteresis == HYSTERESIS_IWAN) {
        double k[IWAN_ELEMENTS], slip[IWAN_ELEMENTS];
        iwan_elements(p, k, slip);
        for (int i = 0; i < IWAN_ELEMENTS; ++i) {
            if (!(k[i] >= 0.0) || !isfinite(k[i])) FAIL("iw_k%d = %g N: expected an element stiffness >= 0 (0: no element)", i + 1, k[i]);
            if (k[i] > 0.0 && !(slip[i] > 0.0 && isfinite(slip[i])))
                FAIL("iw_eps%d = %g with iw_k%d = %g N: expected a positive slip strain", i + 1, slip[i], i + 1, k[i]);
        }
    }
    if (p->creep) {
        const double taus[3] = {p->creep_tau1, p->creep_tau2, p->creep_tau3};
        const double Js[3] = {p->creep_J1, p->creep_J2, p->creep_J3};
        for (int k = 0; k < 3; ++k) {
            if (!(taus[k] > 0.0)) FAIL("creep_tau%d = %g s: expected a positive retardation time", k + 1, taus[k]);
            if (!(Js[k] >= 0.0)) FAIL("creep_J%d = %g 1/N: expected a compliance >= 0", k + 1, Js[k]);
        }
        if (p->creep_law == CREEP_PRIMARY) {
            if (!(p->primary_J >= 0.0) || !isfinite(p->primary_J)) FAIL("primary_J = %g 1/N: expected a compliance >= 0", p->primary_J);
            if (!(p->primary_tau > 0.0) || !isfinite(p->primary_tau)) FAIL("primary_tau = %g s: expected a positive onset time", p->primary_tau);
            if (!(p->primary_n >= 0.0 && p->primary_n <= 1.0)) FAIL("primary_n = %g: expected an exponent in [0, 1] (0: logarithmic)", p->primary_n);
        } else {
            if (!(p->slip_capacity0 >= 0.0)) FAIL("slip_capacity0 = %g: expected >= 0", p->slip_capacity0);
            if (!(p->slip_rate >= 0.0)) FAIL("slip_rate = %g 1/s: expected >= 0", p->slip_rate);
            if (!(p->slip_knee > 0.0)) FAIL("slip_knee = %g: expected > 0", p->slip_knee);
            if (!(p->slip_load_half > 0.0)) FAIL("slip_load_half = %g N: expected > 0", p->slip_load_half);
            if (!(p->slip_load_exponent >= 1.0)) FAIL("slip_load_exponent = %g: expected >= 1", p->slip_load_exponent);
            if (!(p->slip_regen_tau > 0.0)) FAIL("slip_regen_tau = %g s: expected > 0", p->slip_regen_tau);
            if (!(p->slip_limit > 0.0)) FAIL("slip_limit = %g: expected > 0", p->slip_limit);
        }
    }
#undef FAIL
    return 0;
}

/* strain of the static law (elastic, or Kawabata's virgin curve) under tension T */
static int static_strain_at(const tether_model *M, double T, double *eps)
{
    const tether_params *p = &M->p;
    if (p->hysteresis == HYSTERESIS_KAWABATA) {
        *eps = T <= 0.0 ? 0.0 : p->kaw_eps_ref * pow(T / p->kaw_F_ref, 1.0 / kawabata_loading_exponent(p));
        return 0;
    }
    return elastic_strain_below(p, T, M->d.rising_limit, eps);
}

/* The displacement at which a payload displaced to x0 last reversed, ``beyond`` past the span
 * [-|x0|, |x0|]: a reversal inside that span leaves the bank as a monotone displacement from the
 * balance to x0 does (Masing's rule: the branch from it rejoins the virgin curve by x0), so every
 * beyond != 0 is a reversal the bank remembers, and 0 is the monotone displacement. */
/* The load rig's creep under a preload: the first load held for creep_preload_age on a tether free
 * of creep (creep_after_hold), its creep strain added to the elongation the load stretches. */
static int preload_creep(const tether_model *M, double t0, double *y, char *msg, size_t len)
{
    const tether_params *p = &M->p;
    creep_state c;
    const double T0 = input_load(M, t0);
    if (creep_after_hold(p, T0 > 0.0 ? T0 : 0.0, p->creep_preload_age, &c) != 0) {
        snprintf(msg, len, "creep_preload_age = %g s, load = %g N: the slip law did not settle within %ld steps",
                 p->creep_preload_age, T0, CREEP_HOLD_MAX_STEPS);
        return -1;
    }
    y[ST_CREEP_1] = c.kelvin[0];
    y[ST_CREEP_2] = c.kelvin[1];
    y[ST_CREEP_3] = c.kelvin[2];
    y[ST_SLIP] = c.slip;
    y[ST_CAPACITY] = c.capacity;
    y[ST_LOAD_ELONGATION] += (c.kelvin[0] + c.kelvin[1] + c.kelvin[2] + c.slip) * M->in.L0;
    return 0;
}

/* The load rig's Iwan bank at the first load T0: its elements unloaded at the strain the elastic law
 * alone stretches under iwan_relaxed_load (0: a virgin tether, unloaded at zero strain), then brought
 * monotonically to the strain that carries T0 (*eps: the elastic law's alone on entry, the bank's
 * on return). */
static int iwan_rig_start(tether_model *M, double T0, double *eps, char *msg, size_t len)
{
    const tether_params *p = &M->p;
    double eps_r = 0.0;
    if (p->iwan_relaxed_load > 0.0 && elastic_strain_below(p, p->iwan_relaxed_load, M->d.rising_limit, &eps_r) != 0) {
        snprintf(msg, len, "iwan_relaxed_load = %g N: exceeds the largest tension %g N the elastic law carries (at "
                 "strain %g)", p->iwan_relaxed_load, elastic_tension(p, M->d.rising_limit), M->d.rising_limit);
        return -1;
    }
    iwan_reset(&M->d.iwan, eps_r);
    if ((T0 > 0.0 || eps_r > 0.0) && iwan_rig_strain_at(M, T0, *eps, eps) != 0) *eps = M->d.rising_limit;
    iwan_advance(p, &M->d.iwan, *eps);
    M->d.iwan.direction = *eps >= eps_r ? 1 : -1;
    return 0;
}

static double last_reversal(double x0, double beyond)
{
    return beyond > 0.0 ? fabs(x0) + beyond : -fabs(x0) + beyond;
}

/* The payload's angular frequency [1/s] on the tether's stiffness at its balance stretch. */
static double swing_rate(const tether_model *M)
{
    const double k = static_stiffness(M, M->d.balance_elongation / M->in.L0) / M->in.L0;
    return sqrt(fmax(k, 0.0) / M->d.effective_mass);
}

int tether_initialize(tether_model *M, double t0, double *y, char *msg, size_t len)
{
    const tether_params *p = &M->p;
    if (tether_check(M, msg, len) != 0) return -1;
    memset(y, 0, sizeof(double) * TETHER_NUMBER_OF_STATES);
    kawabata_reset(&M->d.kawabata);
    iwan_reset(&M->d.iwan, 0.0);
    M->d.balance_elongation = 0.0;
    M->d.carried_mass = M->d.effective_mass = M->d.swing_rate = 0.0;
    M->d.warned_rising_limit = 0;
    M->d.rising_limit = elastic_rising_limit(p);
    M->d.compression_limit = elastic_compression_limit(p);
    const double z0 = p->hysteresis == HYSTERESIS_BOUCWEN ? p->z0 : 0.0;
    double eps;
    if (p->rig == RIG_PAYLOAD) {
        M->d.carried_mass = payload_carried_mass(p, M->in.L0);
        M->d.effective_mass = payload_effective_mass(p, M->in.L0);
        const double W = M->d.carried_mass * p->g - z0;
        if (static_strain_at(M, W, &eps) != 0) {
            snprintf(msg, len, "m = %g kg, line_density = %g kg/m, g = %g m/s2: the weight %g N exceeds the largest "
                     "tension %g N the cubic law carries (at strain %g, where dF/deps reaches 0)", p->m,
                     p->line_density, p->g, W, elastic_tension(p, M->d.rising_limit), M->d.rising_limit);
            return -1;
        }
        M->d.balance_elongation = eps * M->in.L0;
        M->d.swing_rate = swing_rate(M);
        y[ST_DISPLACEMENT] = p->x0;
        y[ST_VELOCITY] = p->v0;
        if (p->hysteresis == HYSTERESIS_IWAN) {
            /* the elements are unloaded at the balance (a tether shaken down under its payload);
             * the payload is then displaced monotonically to its last reversal, then to x0 */
            const double x_r = last_reversal(p->x0, p->last_reversal_beyond);
            const double eps_r = iwan_strain(M, (M->d.balance_elongation + x_r) / M->in.L0);
            const double eps0 = iwan_strain(M, (M->d.balance_elongation + p->x0) / M->in.L0);
            iwan_reset(&M->d.iwan, iwan_strain(M, eps));
            iwan_advance(p, &M->d.iwan, eps_r);
            iwan_advance(p, &M->d.iwan, eps0);
            M->d.iwan.direction = p->x0 >= x_r ? 1 : -1;
        }
    } else if (p->rig == RIG_LOAD) {
        const double T0 = input_load(M, t0) - z0;
        if (static_strain_at(M, T0, &eps) != 0) {
            snprintf(msg, len, "load = %g N: exceeds the largest tension %g N the cubic law carries (at strain %g)",
                     input_load(M, t0), elastic_tension(p, M->d.rising_limit), M->d.rising_limit);
            return -1;
        }
        if (p->hysteresis == HYSTERESIS_IWAN && iwan_rig_start(M, T0, &eps, msg, len) != 0) return -1;
        y[ST_LOAD_ELONGATION] = eps * M->in.L0;
    } else if (p->hysteresis == HYSTERESIS_IWAN) {
        /* element rig: unloaded at zero strain, brought to the first elongation monotonically */
        const double eps0 = iwan_strain(M, M->in.elongation / M->in.L0);
        iwan_advance(p, &M->d.iwan, eps0);
        M->d.iwan.direction = eps0 >= 0.0 ? 1 : -1;
    }
    y[ST_HYSTERETIC_FORCE] = z0;
    y[ST_CAPACITY] = p->creep && p->creep_law == CREEP_KELVIN_SLIP ? p->slip_capacity0 : 0.0;
    if (p->creep && p->rig == RIG_LOAD && p->creep_preload_age > 0.0 && preload_creep(M, t0, y, msg, len) != 0)
        return -1;
    /* initial slack mode: taut only where the tether is stretched and pulls */
    M->d.taut = 1;
    if (slack_active(M)) {
        tether_instant s;
        evaluate(M, t0, y, &s);
        M->d.taut = s.eps_m > 0.0 && s.T_raw > 0.0;
    }
    return 0;
}

void tether_derivatives(const tether_model *M, double t, const double *y, double *ydot)
{
    const tether_params *p = &M->p;
    tether_instant s;
    evaluate(M, t, y, &s);
    memset(ydot, 0, sizeof(double) * TETHER_NUMBER_OF_STATES);
    if (p->rig == RIG_PAYLOAD) {
        ydot[ST_DISPLACEMENT] = s.udot;
        /* M_eff x'' = M_w g + f - T, written so that M_w = M_eff = m gives g + (f - T) / m exactly */
        const double M_eff = M->d.effective_mass;
        ydot[ST_VELOCITY] = p->g * (M->d.carried_mass / M_eff) + (input_force(M, t) - s.T) / M_eff;
    } else if (p->rig == RIG_LOAD) {
        ydot[ST_LOAD_ELONGATION] = s.udot;
    }
    if (p->hysteresis == HYSTERESIS_BOUCWEN) {
        /* a slack tether is shortened, not compressed: its fibres stay at zero strain and the
         * friction between them sees no motion, so the hysteretic force holds its value until
         * the tether is stretched again */
        const int fibres_still = slack_active(M) && !M->d.taut && s.eps_m <= 0.0;
        ydot[ST_HYSTERETIC_FORCE] = fibres_still ? 0.0 : boucwen_rate(p, s.x, s.L0 * s.eps_m_rate, s.z);
    }
    if (p->creep) {
        ydot[ST_CREEP_1] = s.creep_rate.kelvin[0];
        ydot[ST_CREEP_2] = s.creep_rate.kelvin[1];
        ydot[ST_CREEP_3] = s.creep_rate.kelvin[2];
        ydot[ST_SLIP] = s.creep_rate.slip;
        ydot[ST_CAPACITY] = s.creep_rate.capacity;
    }
}

void tether_event_indicators(const tether_model *M, double t, const double *y, double *g)
{
    tether_instant s;
    evaluate(M, t, y, &s);
    for (int i = 0; i < TETHER_NUMBER_OF_EVENT_INDICATORS; ++i) g[i] = 1.0;
    if (slack_active(M)) {
        /* taut: an event when the strain or the pull falls below -band; slack: when both rise above +band */
        const double sgn = M->d.taut ? 1.0 : -1.0;
        g[EV_SLACK_STRAIN] = s.eps_m + sgn * TETHER_SLACK_STRAIN_BAND;
        g[EV_SLACK_TENSION] = s.T_raw + sgn * TETHER_SLACK_TENSION_BAND;
    }
    if (M->p.hysteresis == HYSTERESIS_KAWABATA) {
        const kawabata_memory *k = &M->d.kawabata;
        g[EV_KAWABATA_RATE] = k->direction * s.eps_m_rate + TETHER_REVERSAL_RATE_BAND;
        double eb;
        if (kawabata_target(k, &eb)) g[EV_KAWABATA_TARGET] = k->direction * (eb - s.eps_m);
    }
    if (M->p.hysteresis == HYSTERESIS_IWAN)
        g[EV_KAWABATA_RATE] = M->d.iwan.direction * s.eps_h_rate + TETHER_REVERSAL_RATE_BAND;
}

int tether_event_update(tether_model *M, double t, const double *y, char *msg, size_t len)
{
    int switches = 0;
    size_t used = 0;
    if (msg && len) msg[0] = '\0';
#define NOTE(...) do { if (msg && used < len) used += (size_t)snprintf(msg + used, len - used, __VA_ARGS__); } while (0)
    if (M->p.hysteresis == HYSTERESIS_KAWABATA) {
        for (int guard = 0; guard < 2 * KAWABATA_MAX_REVERSALS; ++guard) {
            tether_instant s;
            evaluate(M, t, y, &s);
            kawabata_memory *k = &M->d.kawabata;
            double eb;
            if (k->direction * s.eps_m_rate <= -TETHER_REVERSAL_RATE_BAND) {
                if (M->p.rig == RIG_LOAD) {
                    /* under load control the turning point carries exactly the applied load: record
                     * it on the branch, so that a return to this load closes the loop exactly (the
                     * branches are flat at their ends: a mismatch of 1e-8 N would shift the strain
                     * by 1e-5) */
                    kawabata_reverse(&M->p, k, kawabata_strain_at(&M->p, k, s.T), s.T);
                } else {
                    kawabata_reverse(&M->p, k, s.eps_m, s.F);
                }
                NOTE("t = %.17g s: Kawabata reversal to %s at strain %.9g, tension %.9g N. ", t,
                     k->direction > 0 ? "reloading" : "unloading", s.eps_m, s.F);
                ++switches;
            } else if (kawabata_target(k, &eb) && k->direction * (eb - s.eps_m) <= 0.0) {
                kawabata_rejoin(k);
                NOTE("t = %.17g s: Kawabata branch rejoins the older branch at strain %.9g. ", t, eb);
                ++switches;
            } else {
                break;
            }
        }
    }
    if (M->p.hysteresis == HYSTERESIS_IWAN) {
        tether_instant s;
        evaluate(M, t, y, &s);
        iwan_memory *w = &M->d.iwan;
        if (w->direction * s.eps_h_rate <= -TETHER_REVERSAL_RATE_BAND) {
            iwan_reverse(&M->p, w, s.eps_h);
            NOTE("t = %.17g s: Iwan reversal to %s at strain %.9g, friction force %.9g N. ", t,
                 w->direction > 0 ? "reloading" : "unloading", s.eps_h, s.z);
            ++switches;
        }
    }
    if (slack_active(M)) {
        tether_instant s;
        evaluate(M, t, y, &s);
        int taut = M->d.taut;
        if (taut && (s.eps_m <= -TETHER_SLACK_STRAIN_BAND || s.T_raw <= -TETHER_SLACK_TENSION_BAND)) taut = 0;
        else if (!taut && s.eps_m >= TETHER_SLACK_STRAIN_BAND && s.T_raw >= TETHER_SLACK_TENSION_BAND) taut = 1;
        if (taut != M->d.taut) {
            M->d.taut = taut;
            NOTE("t = %.17g s: tether goes %s (strain %.6g, unclamped tension %.6g N). ", t,
                 taut ? "taut" : "slack", s.eps_m, s.T_raw);
            ++switches;
        }
    }
#undef NOTE
    return switches;
}

void tether_compute_outputs(const tether_model *M, double t, const double *y, tether_outputs *o)
{
    tether_instant s;
    double ydot[TETHER_NUMBER_OF_STATES];
    evaluate(M, t, y, &s);
    tether_derivatives(M, t, y, ydot);
    memset(o, 0, sizeof *o);
    o->tension = s.T;
    o->elongation = s.u;
    o->total_elongation = s.u;
    o->strain = s.u / s.L0;
    o->displacement = s.u - M->d.balance_elongation;
    o->velocity = s.udot;
    o->load_elongation = y[ST_LOAD_ELONGATION];
    o->hysteretic_force = y[ST_HYSTERETIC_FORCE];
    o->creep_strain_1 = y[ST_CREEP_1];
    o->creep_strain_2 = y[ST_CREEP_2];
    o->creep_strain_3 = y[ST_CREEP_3];
    o->slip_strain = y[ST_SLIP];
    o->slip_capacity = y[ST_CAPACITY];
    o->der_displacement = ydot[ST_DISPLACEMENT];
    o->der_velocity = ydot[ST_VELOCITY];
    o->der_load_elongation = ydot[ST_LOAD_ELONGATION];
    o->der_hysteretic_force = ydot[ST_HYSTERETIC_FORCE];
    o->der_creep_strain_1 = ydot[ST_CREEP_1];
    o->der_creep_strain_2 = ydot[ST_CREEP_2];
    o->der_creep_strain_3 = ydot[ST_CREEP_3];
    o->der_slip_strain = ydot[ST_SLIP];
    o->der_slip_capacity = ydot[ST_CAPACITY];
    o->balance_elongation = M->d.balance_elongation;
    o->effective_mass = M->d.effective_mass;
    o->creep_total = s.eps_c;
    o->is_slack = slack_active(M) && !M->d.taut;
    o->mechanical_strain = s.eps_m;
    o->raw_tension = s.T_raw;
}

void tether_nominals(const tether_model *M, double *nominal)
{
    const double L0 = M->in.L0;
    nominal[ST_DISPLACEMENT] = 1e-3 * L0;
    nominal[ST_VELOCITY] = 1e-2 * L0;
    nominal[ST_LOAD_ELONGATION] = 1e-2 * L0;
    nominal[ST_HYSTERETIC_FORCE] = 1.0;
    nominal[ST_CREEP_1] = nominal[ST_CREEP_2] = nominal[ST_CREEP_3] = 1e-4;
    nominal[ST_SLIP] = nominal[ST_CAPACITY] = 1e-4;
}

/* The fastest rate [1/s] at which a dissipative law of the payload rig relaxes: the damping's
 * coefficient at rest over the payload's mass (a dry friction's smoothed sign is steepest there),
 * and a Bouc-Wen force's relaxation onto its bound while the tether moves at the speed scale of
 * tether_nominals (boucwen_saturation_length). */
static double fastest_relaxation_rate(const tether_model *M)
{
    double nominal[TETHER_NUMBER_OF_STATES];
    tether_nominals(M, nominal);
    double rate = damping_coefficient(&M->p, 0.0, 0.0, M->d.swing_rate) / M->d.effective_mass;
    if (M->p.hysteresis == HYSTERESIS_BOUCWEN)
        rate = fmax(rate, nominal[ST_VELOCITY] / boucwen_saturation_length(&M->p));
    return rate;
}

int tether_is_stiff(const tether_model *M)
{
    if (M->p.integrator == INTEGRATOR_BDF) return 1;
    if (M->p.integrator == INTEGRATOR_ADAMS) return 0;
    if (M->p.creep || M->p.rig == RIG_LOAD) return 1;
    return M->p.rig == RIG_PAYLOAD && fastest_relaxation_rate(M) > TETHER_STIFF_RELAXATION * M->d.swing_rate;
}

int tether_check_range(tether_model *M, double t, const double *y, char *msg, size_t len)
{
    if (M->p.stiffness != STIFFNESS_CUBIC || M->p.hysteresis == HYSTERESIS_KAWABATA || M->d.warned_rising_limit)
        return 0;
    tether_instant s;
    evaluate(M, t, y, &s);
    if (slack_active(M) && !M->d.taut) return 0;
    const double upper = M->d.rising_limit, lower = M->d.compression_limit;
    if (s.eps_m > upper || s.eps_m < lower) {
        M->d.warned_rising_limit = 1;
        snprintf(msg, len, "t = %.9g s: strain %.6g is outside [%.6g, %.6g], where the cubic law a1 = %g, a2 = %g, "
                 "a3 = %g (power term pow_F = %g, pow_eps = %g, pow_n = %g) rises (beyond, dF/deps <= 0); results "
                 "there are an extrapolation of the fit",
                 t, s.eps_m, lower, upper, M->p.a1, M->p.a2, M->p.a3, M->p.pow_F, M->p.pow_eps, M->p.pow_n);
        return 1;
    }
    return 0;
}

int tether_runaway(const tether_model *M, double t, const double *y, char *msg, size_t len)
{
    tether_instant s;
    evaluate(M, t, y, &s);
    if (!(fabs(s.u / s.L0) <= TETHER_RUNAWAY_STRAIN)) {
        snprintf(msg, len, "t = %.9g s: strain %.6g is beyond +-%g: the simulation has run away "
                 "(e.g. a compressed cubic law without slack, or a violent input)", t, s.u / s.L0, TETHER_RUNAWAY_STRAIN);
        return 1;
    }
    return 0;
}
