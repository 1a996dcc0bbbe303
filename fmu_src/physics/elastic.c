/* Elastic law: the conventional linear spring, or the paper's cubic tension-strain law
 * F(eps) = a1 eps + a2 eps^2 + a3 eps^3, one law for every length (the paper fits 3 lengths and
 * predicts the 8 m tether from it). In elongation x of a tether of length L0 it reads
 * F = (a1/L0) x + (a2/L0^2) x^2 + (a3/L0^3) x^3.
 *
 * Beside the cubic, a power term pow_F sgn(eps) |eps/pow_eps|^pow_n (pow_n >= 1, the tension
 * pow_F at the reference strain pow_eps): the form of Kawabata's loading curve, a stiffness that
 * grows from zero as a fractional power of the strain, which no cubic follows near eps = 0 (a
 * load test of a power-law tether from 0 to 80 N: the best cubic misses its elongation by 3.9 x
 * noise). pow_F = 0, the default, leaves the cubic alone.
 *
 * The exponential law F(eps) = exp_F (exp(eps / exp_eps) - 1) (stiffness = exponential) is a law of
 * its own, not a term beside the cubic: its stiffness (F + exp_F) / exp_eps rises with the tension
 * without bound, where the cubic's turns over, and the two added together would be a law with five
 * coefficients that no record separates. It rises everywhere, and its inverse is closed:
 * eps = exp_eps ln(1 + T / exp_F), for T > -exp_F.
 *
 * The bilinear law (stiffness = bilinear) is the toe of a braid: a soft stiffness toe_EA while the
 * yarns straighten, up to the corner strain toe_eps, then the full stiffness EA, the corner rounded
 * over the strain toe_width by a softplus: F = toe_EA eps + (EA - toe_EA) toe_width
 * (softplus((eps - toe_eps) / toe_width) - softplus(-toe_eps / toe_width)), F(0) = 0. Its stiffness
 * toe_EA + (EA - toe_EA) logistic((eps - toe_eps) / toe_width) lies between the two slopes, so with
 * both positive it rises everywhere. */
#include <float.h>
#include <math.h>

#include "physics/laws.h"

/* The power term is pow_F y (y^2 + d^2)^((pow_n - 1)/2), y = eps/pow_eps, d = POWER_SMOOTHING:
 * sgn(eps) |y|^pow_n to within 0.5 (pow_n - 1) d^2 / y^2 of itself beyond |y| = d, smooth
 * through eps = 0. The bare |y|^pow_n has an unbounded curvature there, and CVODE's error test
 * failed at h = 3e-9 s where a load test's strain left zero. */
#define POWER_SMOOTHING 1e-3

static int has_power_term(const tether_params *p)
{
    return p->stiffness == STIFFNESS_CUBIC && p->pow_F > 0.0;
}

/* exp(eps / exp_eps), its argument capped where the tension would overflow (a strain of hundreds
 * of exp_eps is far beyond any tether; the runaway check stops a simulation long before) */
#define EXPONENTIAL_MAX_ARGUMENT 700.0
static double exponential_argument(const tether_params *p, double eps)
{
    const double y = eps / p->exp_eps;
    return y < EXPONENTIAL_MAX_ARGUMENT ? y : EXPONENTIAL_MAX_ARGUMENT;
}

/* log(1 + exp(y)) without overflow, and its derivative 1 / (1 + exp(-y)) */
static double softplus(double y)
{
    return y > 0.0 ? y + log1p(exp(-y)) : log1p(exp(y));
}

static double logistic(double y)
{
    if (y >= 0.0) return 1.0 / (1.0 + exp(-y));
    const double e = exp(y);
    return e / (1.0 + e);
}

static double bilinear_tension(const tether_params *p, double eps)
{
    const double w = p->toe_width;
    const double bend = softplus((eps - p->toe_eps) / w) - softplus(-p->toe_eps / w);
    return p->toe_EA * eps + (p->EA - p->toe_EA) * w * bend;
}

double elastic_tension(const tether_params *p, double eps)
{
    if (p->stiffness == STIFFNESS_LINEAR) return p->EA * eps;
    if (p->stiffness == STIFFNESS_BILINEAR) return bilinear_tension(p, eps);
    if (p->stiffness == STIFFNESS_EXPONENTIAL) return p->exp_F * expm1(exponential_argument(p, eps));
    double F = eps * (p->a1 + eps * (p->a2 + eps * p->a3));
    if (has_power_term(p)) {
        const double y = eps / p->pow_eps, s = y * y + POWER_SMOOTHING * POWER_SMOOTHING;
        F += p->pow_F * y * pow(s, 0.5 * (p->pow_n - 1.0));
    }
    return F;
}

double elastic_stiffness(const tether_params *p, double eps)
{
    if (p->stiffness == STIFFNESS_LINEAR) return p->EA;
    if (p->stiffness == STIFFNESS_BILINEAR)
        return p->toe_EA + (p->EA - p->toe_EA) * logistic((eps - p->toe_eps) / p->toe_width);
    if (p->stiffness == STIFFNESS_EXPONENTIAL) return p->exp_F / p->exp_eps * exp(exponential_argument(p, eps));
    double k = p->a1 + eps * (2.0 * p->a2 + 3.0 * eps * p->a3);
    if (has_power_term(p)) {
        const double y = eps / p->pow_eps, s = y * y + POWER_SMOOTHING * POWER_SMOOTHING;
        k += p->pow_F / p->pow_eps * pow(s, 0.5 * (p->pow_n - 1.0)) * (1.0 + (p->pow_n - 1.0) * y * y / s);
    }
    return k;
}

/* With the power term: its stiffness is >= 0 and grows with |eps|, so the law rises wherever the
 * cubic's stiffness does, and can stop rising only past the cubic's root r (the first zero of
 * dF/deps beyond r, on the same side). Steps of 2 % of the strain outward from r to 1000 r, then a
 * bisection; none found: it rises for ever as far as a tether can stretch. */
static double power_root(const tether_params *p, double r)
{
    if (!isfinite(r) || r == 0.0) return r;
    double lo = r;
    for (int k = 0; k < 350; ++k) {
        const double hi = lo * 1.02;
        if (elastic_stiffness(p, hi) <= 0.0) {
            double a = lo, b = hi;
            for (int j = 0; j < 100 && fabs(b - a) > 1e-15 * fabs(b); ++j) {
                const double m = 0.5 * (a + b);
                if (elastic_stiffness(p, m) > 0.0) a = m; else b = m;
            }
            return b;
        }
        lo = hi;
    }
    return r > 0.0 ? HUGE_VAL : -HUGE_VAL;
}

/* the roots of dF/deps = a1 + 2 a2 eps + 3 a3 eps^2 nearest to zero on either side (and with the
 * power term, the zeros of the whole law's stiffness beyond them) */
static void stiffness_roots(const tether_params *p, double *below, double *above)
{
    *below = -HUGE_VAL;
    *above = HUGE_VAL;
    if (p->stiffness != STIFFNESS_CUBIC) return;    /* the others rise everywhere */
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
    if (has_power_term(p)) {
        *above = power_root(p, *above);
        *below = power_root(p, *below);
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

/* The strain in [lo, hi] at which the law (rising there, F(lo) <= T <= F(hi)) carries T:
 * Newton's steps, a bisection wherever one would leave the bracket */
static double strain_in_bracket(const tether_params *p, double T, double lo, double hi)
{
    double e = 0.5 * (lo + hi);
    for (int k = 0; k < 200; ++k) {
        const double f = elastic_tension(p, e) - T;
        if (f > 0.0) hi = e; else lo = e;
        const double d = elastic_stiffness(p, e);
        double next = d > 0.0 ? e - f / d : 0.5 * (lo + hi);
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        if (fabs(next - e) <= 1e-16 * (1.0 + fabs(e))) return next;
        e = next;
    }
    return e;
}

/* The bilinear law's stiffness is at least the smaller slope k, and F(0) = 0: the strain at T
 * lies between 0 and T / k */
static int bilinear_strain(const tether_params *p, double T, double *eps)
{
    const double k = fmin(p->toe_EA, p->EA);
    if (!(k > 0.0)) return -1;
    const double far = T / k;
    *eps = T > 0.0 ? strain_in_bracket(p, T, 0.0, far) : strain_in_bracket(p, T, far, 0.0);
    return isfinite(*eps) ? 0 : -1;
}

int elastic_strain_below(const tether_params *p, double T, double rising_limit, double *eps)
{
    if (T == 0.0) { *eps = 0.0; return 0; }
    if (p->stiffness == STIFFNESS_LINEAR) {
        if (p->EA <= 0.0) return -1;
        *eps = T / p->EA;
        return 0;
    }
    if (p->stiffness == STIFFNESS_BILINEAR) return bilinear_strain(p, T, eps);
    if (p->stiffness == STIFFNESS_EXPONENTIAL) {
        /* compression carries at most exp_F (the law tends to -exp_F) */
        if (!(p->exp_F > 0.0) || !(T > -p->exp_F)) return -1;
        *eps = p->exp_eps * log1p(T / p->exp_F);
        return isfinite(*eps) ? 0 : -1;
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
    double hi = rising_limit;
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
    *eps = strain_in_bracket(p, T, 0.0, hi);
    return 0;
}
