/* Bouc-Wen hysteretic force: the hysteresis term of the paper's full dynamic model, in the
 * generalized form with shape control that the paper cites for the asymmetric hysteresis of
 * Kevlar tethers. */
#include <math.h>

#include "physics/laws.h"

static double sgn(double v) { return (v > 0.0) - (v < 0.0); }

double boucwen_rate(const tether_params *p, double x, double xdot, double z)
{
    const double psi = p->bw_gamma + p->bw_beta * sgn(xdot * z) + p->bw_b2 * sgn(x * xdot) +
                       p->bw_b3 * sgn(x * z) + p->bw_b4 * sgn(xdot) + p->bw_b5 * sgn(z) +
                       p->bw_b6 * sgn(x);
    const double zn = p->bw_n == 1.0 ? fabs(z) : pow(fabs(z), p->bw_n);
    return xdot * (p->bw_A - zn * psi);
}
