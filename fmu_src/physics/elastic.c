/* Elastic law: the conventional linear spring, or the paper's cubic tension-strain law
 * F(eps) = a1 eps + a2 eps^2 + a3 eps^3, one law for every length (the paper fits 3 lengths and
 * predicts the 8 m tether from it). In elongation x of a tether of length L0 it reads
 * F = (a1/L0) x + (a2/L0^2) x^2 + (a3/L0^3) x^3. */
#include <float.h>
#include <math.h>

#include "physics/laws.h"

double elastic_tension(const tether_params *p, double eps)
{
    if (p->stiffness == STIFFNESS_LINEAR) return p->EA * eps;
    return eps * (p->a1 + eps * (p->a2 + eps * p->a3));
}

double elastic_stiffness(const tether_params *p, double eps)
{
    if (p->stiffness == STIFFNESS_LINEAR) return p->EA;
    return p->a1 + eps * (2.0 * p->a2 + 3.0 * eps * p->a3);
}

/* the roots of dF/deps = a1 + 2 a2 eps + 3 a3 eps^2 nearest to zero on either side */
static void stiffness_roots(const tether_params *p, double *below, double *above)
{
    *below = -HUGE_VAL;
    *above = HUGE_VAL;
    if (p->stiffness == STIFFNESS_LINEAR) return;
    const double a = 3.0 * p->a3, b = 2.0 * p->a2, c = p->a1;
    if (c <= 0.0) { *below = *above = 0.0; return; }
    double r[2];
    int n = 0;
    if (a == 0.0) {
        if (b != 0.0) r[n++] = -c / b;
    } else {
        const double disc = b * b - 4.0 * a * c;
        if (disc >= 0.0) {
            /* the form without cancellation: with a1 tiny against a2 the textbook form returned
             * 0 for the small root, the law looked rising for ever, and the bracket never closed */
            const double q = -0.5 * (b + (b >= 0.0 ? 1.0 : -1.0) * sqrt(disc));
            r[n++] = q / a;
            if (q != 0.0) r[n++] = c / q;
        }
    }
    for (int k = 0; k < n; ++k) {
        if (r[k] > 0.0 && r[k] < *above) *above = r[k];
        if (r[k] < 0.0 && r[k] > *below) *below = r[k];
    }
}

double elastic_rising_limit(const tether_params *p)
{
    double below, above;
    stiffness_roots(p, &below, &above);
    return above;
}

double elastic_compression_limit(const tether_params *p)
{
    double below, above;
    stiffness_roots(p, &below, &above);
    return below;
}

int elastic_strain_at(const tether_params *p, double T, double *eps)
{
    if (T == 0.0) { *eps = 0.0; return 0; }
    if (p->stiffness == STIFFNESS_LINEAR) {
        if (p->EA <= 0.0) return -1;
        *eps = T / p->EA;
        return 0;
    }
    if (T < 0.0) {
        /* compression (slack off): Newton from the linear guess, the cubic's slope at small
         * negative strain is a1 */
        double e = T / p->a1;
        for (int k = 0; k < 100; ++k) {
            const double de = (elastic_tension(p, e) - T) / elastic_stiffness(p, e);
            e -= de;
            if (fabs(de) <= 1e-15 * (1.0 + fabs(e))) break;
        }
        *eps = e;
        return isfinite(e) ? 0 : -1;
    }
    /* bracket on the rising part [0, limit], then safeguarded Newton */
    double hi = elastic_rising_limit(p);
    if (!isfinite(hi)) {
        /* rising for ever: double until the tension is passed (bounded: the doubling leaves the
         * finite numbers after at most ~2100 steps, and a law that never reaches T is refused) */
        hi = T / p->a1;
        if (!(hi > 0.0)) hi = DBL_MIN;
        for (int k = 0; elastic_tension(p, hi) < T; ++k) {
            if (k > 2200 || !isfinite(hi)) return -1;
            hi *= 2.0;
        }
    } else if (!(elastic_tension(p, hi) >= T)) {
        return -1;
    }
    double lo = 0.0, e = 0.5 * hi;
    for (int k = 0; k < 200; ++k) {
        const double f = elastic_tension(p, e) - T;
        if (f > 0.0) hi = e; else lo = e;
        const double d = elastic_stiffness(p, e);
        double next = d > 0.0 ? e - f / d : 0.5 * (lo + hi);
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        if (fabs(next - e) <= 1e-16 * (1.0 + fabs(e))) { e = next; break; }
        e = next;
    }
    *eps = e;
    return 0;
}
