/* Damping (paper: "the damping coefficient of the tether can be considered as a dynamic changed
 * term related to the displacement"). Kevlar tethers show high damping at large amplitude and very
 * low damping at small amplitude (Jerry and Larry, cited in the paper): c(x) reads the displacement,
 * the amplitude law the same c(.) at the amplitude of the swing, which a forced record that sweeps
 * through its resonance tells apart from the displacement (docs/models.md). */
#include <math.h>

#include "physics/laws.h"

#define DAMPING_TABLE_KNOTS 6

/* The tabulated part of c(x): 0 at x = 0, c_table_k at |x| = k dx, held at the last value beyond
 * the last knot, and in between the monotone cubic Hermite interpolant (Fritsch-Carlson): smooth
 * (C1), level at x = 0 as a smooth even c(x) is and at the last knot where it joins the held
 * value, and never overshooting the knots. It lets c(x) take any shape the data show (levelling
 * off, a threshold), where the polynomial fixes one; a straight line between knots put a kink in
 * every knot and a slope at x = 0 that a smooth damping law does not have. */
static double damping_table(const tether_params *p, double ax)
{
    if (!(p->c_table_dx > 0.0)) return 0.0;
    enum { N = DAMPING_TABLE_KNOTS };
    const double y[N + 1] = {0.0, p->c_table_1, p->c_table_2, p->c_table_3, p->c_table_4, p->c_table_5, p->c_table_6};
    const double s = ax / p->c_table_dx;
    if (!(s < N)) return y[N]; /* also NaN: never an index */
    const int k = (int)s; /* 0 <= s < N here: NaN and huge values were held above */
    const double f = s - k;
    /* slopes per knot spacing: 0 at both ends; inside, the Fritsch-Carlson weighted harmonic mean
     * of the neighbouring secants (0 where they differ in sign: an extremum stays at its knot) */
    double d[2];
    for (int i = 0; i < 2; ++i) {
        const int j = k + i;
        if (j == 0 || j == N) {
            d[i] = 0.0;
            continue;
        }
        const double a = y[j] - y[j - 1], b = y[j + 1] - y[j];
        d[i] = (a * b > 0.0) ? 2.0 * a * b / (a + b) : 0.0;
    }
    const double f2 = f * f, f3 = f2 * f;
    return (2 * f3 - 3 * f2 + 1) * y[k] + (f3 - 2 * f2 + f) * d[0] + (-2 * f3 + 3 * f2) * y[k + 1] + (f3 - f2) * d[1];
}

/* The Coulomb (dry-friction) part as a coefficient: the force c_coulomb tanh(v / coulomb_v) of
 * yarns rubbing on each other, a friction force of nearly constant size against the motion, its
 * sign smoothed over coulomb_v; divided by v, with the limit c_coulomb / coulomb_v at v = 0
 * (tanh(r) / r is exact to rounding for any r != 0: tanh(r) rounds to r where r is small). */
static double damping_coulomb(const tether_params *p, double v)
{
    if (!(p->c_coulomb > 0.0)) return 0.0;
    const double r = v / p->coulomb_v;
    return p->c_coulomb / p->coulomb_v * (r == 0.0 ? 1.0 : tanh(r) / r);
}

/* The magnitude c(.) reads: the displacement |x|, or (amplitude law) the amplitude of the swing the
 * payload is on, sqrt(x^2 + (v / omega)^2) with omega its angular frequency at the balance: constant
 * over a free swing of a linear tether, where |x| runs from 0 to the amplitude twice a cycle. Outside
 * the payload rig (omega = 0) no swing defines an amplitude, and the law reads |x|. */
static double damping_magnitude(const tether_params *p, double x, double v, double swing_rate)
{
    if (p->damping == DAMPING_AMPLITUDE && swing_rate > 0.0) return hypot(x, v / swing_rate);
    return fabs(x);
}

double damping_coefficient(const tether_params *p, double x, double v, double swing_rate)
{
    if (p->damping == DAMPING_VISCOUS) return p->c0;
    if (p->damping == DAMPING_COULOMB) {
        /* viscous plus dry friction alone: the law of a damping that falls with amplitude */
        const double c = p->c0 + damping_coulomb(p, v);
        return c > 0.0 ? c : 0.0;
    }
    const double a = damping_magnitude(p, x, v, swing_rate);
    /* c_drag |v|: the damping force c_drag |v| v of a body moving through air or water, which
     * also damps large amplitudes more than small ones, but through the velocity */
    const double c = p->c0 + p->c1 * a + p->c2 * a * a + damping_table(p, a) + p->c_drag * fabs(v)
                     + damping_coulomb(p, v);
    return c > 0.0 ? c : 0.0; /* a damper takes energy out, never puts it in */
}
