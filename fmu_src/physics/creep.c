/* Creep (paper: three stages; the paper gives no law, this one is ours).
 *
 * Recoverable (viscoelastic) creep: Kelvin cells in series, eps_k' = (J_k T - eps_k) / tau_k, with
 * retardation times from half an hour to days.
 *
 * Unrecoverable creep: slip between yarns that closes the clearance of the braid. The paper
 * explains it so: under load the tether first tightens, then friction lets molecular chains and
 * yarns slip until the clearance is used up; on unloading the braid loosens and some clearance
 * reopens, but less each time. The slip strain eps_s uses up an available clearance s:
 *   eps_s' = w(T) r s / (s + s_knee)                        (nearly constant rate, then it stops)
 *   s'     = -eps_s' + (1 - w(T)) (s_inf(eps_s) - s) / tau_regen   (clearance reopens unloaded)
 *   s_inf  = s0 max(0, 1 - eps_s / eps_limit),  w(T) = T^k / (T^k + T_half^k)
 * so the first loading slips at a nearly constant rate for about an hour (the paper's linear
 * stage), and each repeated loading slips less (the paper's 8, 5 and 3 mm).
 *
 * Primary creep (creep_law = primary, in the slip's place; for tethers that are not ours): a
 * viscoplastic strain that hardens as it accumulates, eps_p' = (C/tau) (1 + n eps_p/C)^((n-1)/n),
 * C = J T (laws.h). Under a constant load it is Findley's power of time (C/n)((1 + t/tau)^n - 1),
 * or at n = 0 the logarithm C ln(1 + t/tau); a load stepped up continues from the strain reached
 * (the time equivalent to it under the new load); unloaded it stops and stays (the Kelvin cells
 * beside it give the recovery). */
#include <math.h>

#include "physics/laws.h"

double creep_slip_activation(const tether_params *p, double T)
{
    if (T <= 0.0) return 0.0;
    const double r = pow(p->slip_load_half / T, p->slip_load_exponent);
    return 1.0 / (1.0 + r);
}

double creep_primary_rate(const tether_params *p, double T, double eps_p)
{
    if (!(T > 0.0) || !(p->primary_J > 0.0)) return 0.0;
    const double C = p->primary_J * T, x = (eps_p > 0.0 ? eps_p : 0.0) / C, n = p->primary_n;
    /* (1 + n x)^((n - 1)/n) through log1p: continuous into exp(-x) as n -> 0 */
    const double hardening = n > 0.0 ? exp((n - 1.0) / n * log1p(n * x)) : exp(-x);
    return C / p->primary_tau * hardening;
}

void creep_rates(const tether_params *p, double T, const creep_state *s, creep_state *rate)
{
    const double J[CREEP_KELVIN_CELLS] = {p->creep_J1, p->creep_J2, p->creep_J3};
    const double tau[CREEP_KELVIN_CELLS] = {p->creep_tau1, p->creep_tau2, p->creep_tau3};
    for (int k = 0; k < CREEP_KELVIN_CELLS; ++k) rate->kelvin[k] = (J[k] * T - s->kelvin[k]) / tau[k];
    if (p->creep_law == CREEP_PRIMARY) {
        rate->slip = creep_primary_rate(p, T, s->slip);
        rate->capacity = 0.0;
        return;
    }
    const double w = creep_slip_activation(p, T);
    const double cap = s->capacity > 0.0 ? s->capacity : 0.0;
    const double slip_rate = w * p->slip_rate * cap / (cap + p->slip_knee);
    double s_inf = p->slip_capacity0 * (1.0 - s->slip / p->slip_limit);
    if (s_inf < 0.0) s_inf = 0.0;
    rate->slip = slip_rate;
    rate->capacity = -slip_rate + (1.0 - w) * (s_inf - s->capacity) / p->slip_regen_tau;
}

/* the slip law's state (slip, clearance) under a constant T: the rates of creep_rates */
static void slip_rates(const tether_params *p, double T, const double y[2], double dy[2])
{
    creep_state s = {{0.0, 0.0, 0.0}, y[0], y[1]}, r;
    creep_rates(p, T, &s, &r);
    dy[0] = r.slip;
    dy[1] = r.capacity;
}

/* a step of the slip law's state (slip, clearance) at tension T: no longer than its fastest
 * relaxation time (the slip's d(slip')/d(clearance) = w r knee / (cap + knee)^2 and the clearance's
 * reopening (1 - w) / tau_regen, where classical Runge-Kutta is stable and within 2 % of the decay),
 * and no longer than a twentieth of the time in which the state would change by its own size (the
 * clearance plus the knee, the slip) at its current rates */
static double slip_step(const tether_params *p, double T, const double y[2], const double dy[2])
{
    const double w = creep_slip_activation(p, T), cap = y[1] > 0.0 ? y[1] : 0.0, size = cap + p->slip_knee;
    double h = HUGE_VAL;
    if (w * p->slip_rate > 0.0) h = size * size / (w * p->slip_rate * p->slip_knee);
    if (1.0 - w > 0.0 && p->slip_regen_tau / (1.0 - w) < h) h = p->slip_regen_tau / (1.0 - w);
    const double change = fabs(dy[0]) + fabs(dy[1]);
    if (change > 0.0 && 0.05 * (size + fabs(y[0])) / change < h) h = 0.05 * (size + fabs(y[0])) / change;
    return h;
}

static int slip_after_hold(const tether_params *p, double T, double age, double y[2])
{
    double t = 0.0;
    for (long k = 0; t < age; ++k) {
        if (k >= CREEP_HOLD_MAX_STEPS) return -1;
        double d1[2], d2[2], d3[2], d4[2], m[2];
        slip_rates(p, T, y, d1);
        const double left = age - t;
        if ((fabs(d1[0]) + fabs(d1[1])) * left < 1e-15) break;   /* settled: nothing left to happen */
        const double h = fmin(left, slip_step(p, T, y, d1));
        for (int i = 0; i < 2; ++i) m[i] = y[i] + 0.5 * h * d1[i];
        slip_rates(p, T, m, d2);
        for (int i = 0; i < 2; ++i) m[i] = y[i] + 0.5 * h * d2[i];
        slip_rates(p, T, m, d3);
        for (int i = 0; i < 2; ++i) m[i] = y[i] + h * d3[i];
        slip_rates(p, T, m, d4);
        for (int i = 0; i < 2; ++i) y[i] += h / 6.0 * (d1[i] + 2.0 * d2[i] + 2.0 * d3[i] + d4[i]);
        t += h;
    }
    return 0;
}

int creep_after_hold(const tether_params *p, double T, double age, creep_state *s)
{
    const double J[CREEP_KELVIN_CELLS] = {p->creep_J1, p->creep_J2, p->creep_J3};
    const double tau[CREEP_KELVIN_CELLS] = {p->creep_tau1, p->creep_tau2, p->creep_tau3};
    s->slip = 0.0;
    s->capacity = p->creep_law == CREEP_KELVIN_SLIP ? p->slip_capacity0 : 0.0;
    for (int k = 0; k < CREEP_KELVIN_CELLS; ++k) s->kelvin[k] = -J[k] * T * expm1(-age / tau[k]);
    if (!(age > 0.0) || !(T > 0.0)) return 0;
    if (p->creep_law == CREEP_PRIMARY) {
        const double C = p->primary_J * T, n = p->primary_n, x = log1p(age / p->primary_tau);
        s->slip = n > 0.0 ? C / n * expm1(n * x) : C * x;
        return 0;
    }
    double y[2] = {s->slip, s->capacity};
    if (slip_after_hold(p, T, age, y) != 0) return -1;
    s->slip = y[0];
    s->capacity = y[1];
    return 0;
}
