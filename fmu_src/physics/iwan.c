/* Iwan hysteresis: the friction between the fibres of a braid as a bank of parallel Jenkins
 * elements (a spring k_i in series with a Coulomb slider that slips once the spring's strain
 * reaches eps_i), in parallel with the elastic law. Its force is a Prandtl-Ishlinskii sum of play
 * operators: rate-independent, Masing-type (an unloading branch is the loading curve scaled by
 * two), and minor loops close by themselves, with no turning-point stack: each element remembers
 * only its own spring strain.
 *
 * Between two reversals the strain is monotone, so each element's spring strain is its value at
 * the last reversal moved by the strain since, clipped to the slip range:
 *   H(eps) = sum_i k_i clip(q_i + eps - eps_ref, -eps_i, eps_i).
 * A reversal records q_i at the turning point (iwan_reverse); nothing else is remembered. */
#include <math.h>

#include "physics/laws.h"

void iwan_elements(const tether_params *p, double k[IWAN_ELEMENTS], double slip[IWAN_ELEMENTS])
{
    const double kk[IWAN_ELEMENTS] = {p->iw_k1,  p->iw_k2,  p->iw_k3,  p->iw_k4,  p->iw_k5,  p->iw_k6,
                                      p->iw_k7,  p->iw_k8,  p->iw_k9,  p->iw_k10, p->iw_k11, p->iw_k12,
                                      p->iw_k13, p->iw_k14, p->iw_k15, p->iw_k16};
    const double ee[IWAN_ELEMENTS] = {p->iw_eps1,  p->iw_eps2,  p->iw_eps3,  p->iw_eps4,  p->iw_eps5,
                                      p->iw_eps6,  p->iw_eps7,  p->iw_eps8,  p->iw_eps9,  p->iw_eps10,
                                      p->iw_eps11, p->iw_eps12, p->iw_eps13, p->iw_eps14, p->iw_eps15,
                                      p->iw_eps16};
    for (int i = 0; i < IWAN_ELEMENTS; ++i) {
        k[i] = kk[i];
        slip[i] = ee[i];
    }
}

static double clip(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }

void iwan_reset(iwan_memory *mem, double eps_unloaded)
{
    mem->direction = 1;
    mem->eps_ref = eps_unloaded;
    for (int i = 0; i < IWAN_ELEMENTS; ++i) mem->q[i] = 0.0;
}

double iwan_force(const tether_params *p, const iwan_memory *mem, double eps)
{
    double k[IWAN_ELEMENTS], slip[IWAN_ELEMENTS], H = 0.0;
    iwan_elements(p, k, slip);
    const double d = eps - mem->eps_ref;
    for (int i = 0; i < IWAN_ELEMENTS; ++i)
        if (k[i] > 0.0) H += k[i] * clip(mem->q[i] + d, -slip[i], slip[i]);
    return H;
}

double iwan_stiffness(const tether_params *p, const iwan_memory *mem, double eps)
{
    double k[IWAN_ELEMENTS], slip[IWAN_ELEMENTS], K = 0.0;
    iwan_elements(p, k, slip);
    const double d = eps - mem->eps_ref;
    for (int i = 0; i < IWAN_ELEMENTS; ++i) {
        if (!(k[i] > 0.0)) continue;
        const double w = mem->q[i] + d;
        /* an element sticks while its spring strain lies inside the slip range; on the edge it
         * sticks only when the motion takes it back inside */
        if (mem->direction > 0 ? w < slip[i] : w > -slip[i]) K += k[i];
    }
    return K;
}

void iwan_advance(const tether_params *p, iwan_memory *mem, double eps)
{
    double k[IWAN_ELEMENTS], slip[IWAN_ELEMENTS];
    iwan_elements(p, k, slip);
    const double d = eps - mem->eps_ref;
    for (int i = 0; i < IWAN_ELEMENTS; ++i) mem->q[i] = clip(mem->q[i] + d, -slip[i], slip[i]);
    mem->eps_ref = eps;
}

void iwan_reverse(const tether_params *p, iwan_memory *mem, double eps)
{
    iwan_advance(p, mem, eps);
    mem->direction = -mem->direction;
}
