/* Kawabata loading/unloading hysteresis (paper: "the hysteresis effect under single loading and
 * unloading is fitted well by the Kawabata stress-strain model").
 *
 * From one cycle to (eps_m, F_m): the tensile energy WT, the linearity LT = WT / (F_m eps_m / 2)
 * and the resilience RT = WT'/WT. A linearity that is the same at every strain gives power-law
 * branches:
 *   loading    F = F_m (eps / eps_m)^p,                          p = 2/LT - 1
 *   unloading  F = F_m ((eps - eps_1) / (eps_m - eps_1))^q,      q = 2 (eps_m - eps_1)/(RT LT eps_m) - 1
 * with eps_1 the strain left after unloading (the paper: the recovery range is [eps_1, eps_m]).
 * Our choice: eps_1 = kaw_residual * eps_m, which makes q the same for every cycle.
 *
 * Reversals inside a cycle (the paper gives no rule; ours is Masing-type): a branch that starts at
 * the turning point a runs towards the previous turning point b with the shape of its kind,
 *   reloading  F = F_a + (F_b - F_a) ((eps - eps_a) / (eps_b - eps_a))^p
 *   unloading  F = F_b + (F_a - F_b) ((eps - eps_b) / (eps_a - eps_b))^q
 * Every branch starts at the tension where the last one stopped (continuous tension), and when it
 * reaches b it rejoins the branch that b interrupted, so minor loops close exactly. */
#include <math.h>

#include "physics/laws.h"

double kawabata_loading_exponent(const tether_params *p) { return 2.0 / p->kaw_LT - 1.0; }

double kawabata_unloading_exponent(const tether_params *p)
{
    return 2.0 * (1.0 - p->kaw_residual) / (p->kaw_RT * p->kaw_LT) - 1.0;
}

double kawabata_virgin_tension(const tether_params *p, double eps)
{
    if (eps <= 0.0) return 0.0;
    return p->kaw_F_ref * pow(eps / p->kaw_eps_ref, kawabata_loading_exponent(p));
}

/* The exponent of a nested branch (a minor loop: two or more turning points) spanning `span` in
 * strain and `dF` in tension, whose own exponent is e. An exponent e > 1 makes the branch steepest
 * at its far end from the flat start, e dF / span there; that is capped at KAWABATA_STIFFNESS_CAP
 * times the start stiffness of the outer unloading branch (from R_1), by lowering the exponent
 * towards 1 (the straight chord). Without the cap, a loop nested in the steep start of an
 * unloading branch is q times stiffer than its parent, so a decaying vibration nests loops that
 * stiffen without bound: the period shrinks to nothing and the events pile up (docs/robustness.md). */
static double branch_exponent(const tether_params *p, const kawabata_memory *mem, double e, double span, double dF)
{
    if (mem->n < 2 || !(e > 1.0)) return e;
    const double outer_span = (1.0 - p->kaw_residual) * mem->eps[0];
    const double K_outer = kawabata_unloading_exponent(p) * mem->F[0] / outer_span;
    if (!(K_outer > 0.0) || !isfinite(K_outer)) return e;
    const double e_cap = KAWABATA_STIFFNESS_CAP * K_outer * span / fabs(dF);
    if (!(e_cap < e)) return e;
    return e_cap > 1.0 ? e_cap : 1.0;
}

void kawabata_reset(kawabata_memory *mem)
{
    mem->n = 0;
    mem->direction = 1;
}

/* the point the current branch runs to: (eps_b, F_b); for the outer unloading branch the residual
 * strain at zero tension */
static void branch_end(const tether_params *p, const kawabata_memory *mem, double *eb, double *Fb)
{
    const int n = mem->n;
    if (n >= 2) {
        *eb = mem->eps[n - 2];
        *Fb = mem->F[n - 2];
    } else {
        const double em = mem->eps[0] > 0.0 ? mem->eps[0] : 0.0;
        *eb = p->kaw_residual * em;
        *Fb = 0.0;
    }
}

double kawabata_tension(const tether_params *p, const kawabata_memory *mem, double eps)
{
    const int n = mem->n;
    if (n == 0) return kawabata_virgin_tension(p, eps);
    const double ea = mem->eps[n - 1], Fa = mem->F[n - 1];
    double eb, Fb;
    branch_end(p, mem, &eb, &Fb);
    const double span = mem->direction > 0 ? eb - ea : ea - eb;
    if (!(span > 0.0)) return Fa;
    if (mem->direction > 0) {
        const double s = (eps - ea) / span;
        if (s <= 0.0) return Fa;
        return Fa + (Fb - Fa) * pow(s, branch_exponent(p, mem, kawabata_loading_exponent(p), span, Fb - Fa));
    }
    const double s = (eps - eb) / span;
    if (s <= 0.0) return Fb;
    return Fb + (Fa - Fb) * pow(s, branch_exponent(p, mem, kawabata_unloading_exponent(p), span, Fa - Fb));
}

double kawabata_stiffness(const tether_params *p, const kawabata_memory *mem, double eps)
{
    const int n = mem->n;
    if (n == 0) {
        if (eps <= 0.0) return 0.0;
        const double e = kawabata_loading_exponent(p);
        return p->kaw_F_ref * e * pow(eps / p->kaw_eps_ref, e - 1.0) / p->kaw_eps_ref;
    }
    const double ea = mem->eps[n - 1], Fa = mem->F[n - 1];
    double eb, Fb;
    branch_end(p, mem, &eb, &Fb);
    const double span = mem->direction > 0 ? eb - ea : ea - eb;
    if (!(span > 0.0)) return 0.0;
    if (mem->direction > 0) {
        const double s = (eps - ea) / span, e = branch_exponent(p, mem, kawabata_loading_exponent(p), span, Fb - Fa);
        return s <= 0.0 ? 0.0 : (Fb - Fa) * e * pow(s, e - 1.0) / span;
    }
    const double s = (eps - eb) / span, e = branch_exponent(p, mem, kawabata_unloading_exponent(p), span, Fa - Fb);
    return s <= 0.0 ? 0.0 : (Fa - Fb) * e * pow(s, e - 1.0) / span;
}

double kawabata_strain_at(const tether_params *p, const kawabata_memory *mem, double F)
{
    const int n = mem->n;
    if (F < 0.0) F = 0.0;
    if (n == 0) return p->kaw_eps_ref * pow(F / p->kaw_F_ref, 1.0 / kawabata_loading_exponent(p));
    const double ea = mem->eps[n - 1], Fa = mem->F[n - 1];
    double eb, Fb;
    branch_end(p, mem, &eb, &Fb);
    const double span = mem->direction > 0 ? eb - ea : ea - eb;
    if (!(span > 0.0) || Fa == Fb) return ea;
    if (mem->direction > 0) {
        const double r = (F - Fa) / (Fb - Fa);
        return r <= 0.0 ? ea : ea + span * pow(r, 1.0 / branch_exponent(p, mem, kawabata_loading_exponent(p), span, Fb - Fa));
    }
    const double r = (F - Fb) / (Fa - Fb);
    return r <= 0.0 ? eb : eb + span * pow(r, 1.0 / branch_exponent(p, mem, kawabata_unloading_exponent(p), span, Fa - Fb));
}

void kawabata_reverse(const tether_params *p, kawabata_memory *mem, double eps, double F)
{
    if (mem->n == 1 && mem->direction < 0) {
        /* reloading from the slack end of the outer unloading branch starts at the residual
         * strain: below it the tether carries no tension */
        double eb, Fb;
        branch_end(p, mem, &eb, &Fb);
        if (eps < eb) { eps = eb; F = 0.0; }
    }
    if (mem->n == KAWABATA_MAX_REVERSALS) {
        /* memory full: forget the current branch's start and target (the innermost pair); the new
         * branch then runs to the next older turning point of the same kind */
        mem->n -= 2;
    }
    mem->eps[mem->n] = eps;
    mem->F[mem->n] = F;
    mem->n += 1;
    mem->direction = -mem->direction;
}

int kawabata_target(const kawabata_memory *mem, double *eps_target)
{
    if (mem->n < 2) return 0;
    *eps_target = mem->eps[mem->n - 2];
    return 1;
}

void kawabata_rejoin(kawabata_memory *mem)
{
    if (mem->n >= 2) mem->n -= 2;
}
