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

double boucwen_saturation_length(const tether_params *p)
{
    const double psi = fabs(p->bw_gamma) + fabs(p->bw_beta) + fabs(p->bw_b2) + fabs(p->bw_b3) + fabs(p->bw_b4) +
                       fabs(p->bw_b5) + fabs(p->bw_b6);
    if (!(psi > 0.0) || !(p->bw_A > 0.0) || !(p->bw_n > 0.0)) return INFINITY;
    const double z_bound = pow(p->bw_A / psi, 1.0 / p->bw_n);
    return 1.0 / (p->bw_n * psi * pow(z_bound, p->bw_n - 1.0));
}

void boucwen_path(double A, double beta, double gamma, const double *x, int n, int periodic, double *z)
{
    double zk = 0.0;
    for (int pass = 0; pass < (periodic ? 2 : 1); ++pass) {
        for (int i = 0; i < n; ++i) {
            z[i] = zk;
            const double d = i + 1 < n ? x[i + 1] - x[i] : (periodic ? x[0] - x[n - 1] : 0.0);
            if (d == 0.0) continue;
            const double psi = d * zk > 0.0 ? gamma + beta : gamma - beta;
            const double lam = zk >= 0.0 ? psi : -psi; /* dz/dx = A - lam z */
            const double e = lam * d;
            if (fabs(e) < 1e-8 || e <= -50.0)
                zk += (A - lam * zk) * d; /* nearly linear, or a runaway: one explicit step */
            else {
                const double zs = A / lam;
                zk = zs + (zk - zs) * exp(-e);
            }
            if (!isfinite(zk) || fabs(zk) > 1e12) zk = copysign(1e12, isfinite(zk) ? zk : 1.0);
        }
    }
}
