/* Damping (paper: "the damping coefficient of the tether can be considered as a dynamic changed
 * term related to the displacement"). Kevlar tethers show high damping at large amplitude and very
 * low damping at small amplitude (Jerry and Larry, cited in the paper). */
#include <math.h>

#include "physics/laws.h"

#define DAMPING_TABLE_KNOTS 6

/* The tabulated part of c(x): 0 at x = 0, c_table_k at |x| = k dx, linear in between, held at the
 * last value beyond the last knot. It lets c(x) take any shape the data show (levelling off, a
 * threshold), where the polynomial fixes one. */
static double damping_table(const tether_params *p, double ax)
{
    if (!(p->c_table_dx > 0.0)) return 0.0;
    const double knot[DAMPING_TABLE_KNOTS + 1] = {0.0,          p->c_table_1, p->c_table_2, p->c_table_3,
                                                  p->c_table_4, p->c_table_5, p->c_table_6};
    const double s = ax / p->c_table_dx;
    if (s >= DAMPING_TABLE_KNOTS) return knot[DAMPING_TABLE_KNOTS];
    const int k = (int)s;
    const double f = s - k;
    return knot[k] + f * (knot[k + 1] - knot[k]);
}

double damping_coefficient(const tether_params *p, double x, double v)
{
    if (p->damping == DAMPING_VISCOUS) return p->c0;
    const double ax = fabs(x);
    /* c_drag |v|: the damping force c_drag |v| v of a body moving through air or water, which
     * also damps large amplitudes more than small ones, but through the velocity */
    const double c = p->c0 + p->c1 * ax + p->c2 * x * x + damping_table(p, ax) + p->c_drag * fabs(v);
    return c > 0.0 ? c : 0.0; /* a damper takes energy out, never puts it in */
}
