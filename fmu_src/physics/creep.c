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
