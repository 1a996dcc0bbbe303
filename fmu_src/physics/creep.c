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
 * stage), and each repeated loading slips less (the paper's 8, 5 and 3 mm). */
#include <math.h>

#include "physics/laws.h"

double creep_slip_activation(const tether_params *p, double T)
{
    if (T <= 0.0) return 0.0;
    const double r = pow(p->slip_load_half / T, p->slip_load_exponent);
    return 1.0 / (1.0 + r);
}

void creep_rates(const tether_params *p, double T, const creep_state *s, creep_state *rate)
{
    const double J[CREEP_KELVIN_CELLS] = {p->creep_J1, p->creep_J2, p->creep_J3};
    const double tau[CREEP_KELVIN_CELLS] = {p->creep_tau1, p->creep_tau2, p->creep_tau3};
    for (int k = 0; k < CREEP_KELVIN_CELLS; ++k) rate->kelvin[k] = (J[k] * T - s->kelvin[k]) / tau[k];
    const double w = creep_slip_activation(p, T);
    const double cap = s->capacity > 0.0 ? s->capacity : 0.0;
    const double slip_rate = w * p->slip_rate * cap / (cap + p->slip_knee);
    double s_inf = p->slip_capacity0 * (1.0 - s->slip / p->slip_limit);
    if (s_inf < 0.0) s_inf = 0.0;
    rate->slip = slip_rate;
    rate->capacity = -slip_rate + (1.0 - w) * (s_inf - s->capacity) / p->slip_regen_tau;
}
