/* Damping (paper: "the damping coefficient of the tether can be considered as a dynamic changed
 * term related to the displacement"). Kevlar tethers show high damping at large amplitude and very
 * low damping at small amplitude (Jerry and Larry, cited in the paper). */
#include <math.h>

#include "physics/laws.h"

double damping_coefficient(const tether_params *p, double x)
{
    if (p->damping == DAMPING_VISCOUS) return p->c0;
    return p->c0 + p->c1 * fabs(x) + p->c2 * x * x;
}
