// Levenberg-Marquardt fit of chosen parameters to several experiments jointly, with covariance,
// confidence intervals, correlations and an identifiability analysis (SVD of the Jacobian).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include <Eigen/Dense>
#include <pthread.h>

#include "identify/engine.hpp"

namespace kt {
thread_local std::string last_error;
}

using Eigen::MatrixXd;
using Eigen::VectorXd;

namespace {

// Student t quantile (two-sided 95 %) for dof degrees of freedom (Cornish-Fisher / Hill expansion)
double t_quantile_975(int dof)
{
    const double z = 1.959963984540054;
    if (dof <= 0) return std::numeric_limits<double>::infinity();
    static const double table[] = {12.7062, 4.3027, 3.1824, 2.7764, 2.5706, 2.4469, 2.3646, 2.3060, 2.2622, 2.2281};
    if (dof <= 10) return table[dof - 1];
    const double n = dof, z3 = z * z * z, z5 = z3 * z * z, z7 = z5 * z * z, z9 = z7 * z * z;
    return z + (z3 + z) / (4 * n) + (5 * z5 + 16 * z3 + 3 * z) / (96 * n * n) +
           (3 * z7 + 19 * z5 + 17 * z3 - 15 * z) / (384 * n * n * n) +
           (79 * z9 + 776 * z7 + 1482 * z5 - 1920 * z3 - 945 * z) / (92160 * n * n * n * n);
}

// CPU time of the calling thread so far, in nanoseconds
long long thread_cpu_ns()
{
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (long long)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

// The model's outputs before offset_measured at the last few points a fit simulated (theta and the
// problem's size as the key: a horizon stage shares it with shorter records).
struct RawOutputs {
    static constexpr std::size_t capacity = 8;
    std::mutex m;
    std::deque<std::tuple<VectorXd, int, VectorXd>> at; // (theta, n_res, outputs), newest last

    void put(const VectorXd &th, int n_res, const VectorXd &out)
    {
        std::lock_guard<std::mutex> lock(m);
        at.emplace_back(th, n_res, out);
        if (at.size() > capacity) at.pop_front();
    }
    bool get(const VectorXd &th, int n_res, VectorXd &out)
    {
        std::lock_guard<std::mutex> lock(m);
        for (auto it = at.rbegin(); it != at.rend(); ++it)
            if (std::get<1>(*it) == n_res && std::get<0>(*it).size() == th.size() && std::get<0>(*it) == th) {
                out = std::get<2>(*it);
                return true;
            }
        return false;
    }
};

// a simulated measured column (n samples from v) made residuals in place:
// weight * sample_weight[k] * (model - measured); a non-finite model output fails at any factor
bool to_residuals(const kt_experiment &e, double *v, std::string &err)
{
    const double w = e.weight > 0 ? e.weight : 1.0;
    for (int k = 0; k < e.n; ++k) {
        v[k] = w * (v[k] - e.measured[k]);
        if (!std::isfinite(v[k])) { err = "non-finite residual"; return false; }
        if (e.sample_weight) v[k] *= e.sample_weight[k];
    }
    return true;
}

// the samples of e a fit sees: those of a nonzero sample_weight (every one where there is none)
int fitted_samples(const kt_experiment &e)
{
    if (!e.sample_weight) return e.n;
    int n = 0;
    for (int k = 0; k < e.n; ++k) n += e.sample_weight[k] != 0.0;
    return n;
}

// the least work per sample a crawl cap counts as its start's (a start that barely moves, e.g. a
// record at rest, would otherwise cap its trial points near nothing)
constexpr long long KT_CRAWL_FLOOR_PER_SAMPLE = 2;

struct Problem {
    std::vector<kt::Prepared> exps;
    std::vector<int> par;      // parameter table indices of the free parameters
    // offset_measured's place among them (-1: not free), and the outputs before it of the last
    // points simulated: it adds to the measured column after the simulation, so its difference
    // quotient is the simulated one, to the bit, without a simulation (offset_residuals)
    int offset_j = -1;
    std::shared_ptr<RawOutputs> raw;
    std::vector<int> log_scale; // 1 log, 0 linear
    std::vector<double> sign, scale; // log: p = sign exp(theta); linear: p = scale theta
    VectorXd lo, hi;           // bounds in theta
    int n_res = 0;
    int n_fitted = 0;          // the residuals of a nonzero sample weight: the statistics' sample count
    double rtol_override = 0;
    int n_threads = 1;
    const kt::Limits *limits = nullptr; // deadlines (NULL = none)

    bool out_of_time() const { return limits && limits->hit.load() != 0; }

    double to_p(int j, double th) const { return log_scale[j] ? sign[j] * std::exp(th) : scale[j] * th; }
    double dp_dtheta(int j, double th) const { return log_scale[j] ? sign[j] * std::exp(th) : scale[j]; }
    double to_theta(int j, double p) const { return log_scale[j] ? std::log(p * sign[j]) : p / scale[j]; }

    // residuals at theta; false on a failed simulation. keep_raw: the outputs before offset_measured
    // kept (RawOutputs) where it is free; works (if not NULL): each experiment's simulation work
    bool residuals(const VectorXd &th, VectorXd &r, std::string &err, bool keep_raw = true,
                   std::vector<long long> *works = nullptr) const
    {
        if (works) works->clear();
        r.resize(n_res);
        const bool keep = keep_raw && raw && offset_j >= 0;
        VectorXd before(keep ? n_res : 0);
        int off = 0;
        for (const kt::Prepared &pe : exps) {
            kt::Setup S = pe.base;
            if (rtol_override > 0) S.M.p.rtol = rtol_override;
            for (std::size_t j = 0; j < par.size(); ++j)
                if (!kt::set_parameter(S, par[j], to_p((int)j, th[(Eigen::Index)j]), err)) return false;
            const kt_experiment &e = *pe.e;
            double *out = r.data() + off;
            const double offset = S.meas.offset_measured;
            if (keep) S.meas.offset_measured = 0.0;
            if (!kt::simulate(pe, S, out, err)) return false;
            if (works) works->push_back(kt::last_simulation_work);
            if (keep) {
                std::copy(out, out + e.n, before.data() + off);
                kt::add_measured_offset(pe, offset, out);
            }
            if (!to_residuals(e, out, err)) return false;
            off += e.n;
        }
        if (keep) raw->put(th, n_res, before);
        return true;
    }

    // the residuals at theta from the outputs before offset_measured at a point that differs from
    // theta in offset_measured only: the same arithmetic as residuals() after its simulation
    bool offset_residuals(const VectorXd &th, const VectorXd &before, VectorXd &r) const
    {
        r = before;
        const double offset = to_p(offset_j, th[offset_j]);
        int off = 0;
        std::string err;
        for (const kt::Prepared &pe : exps) {
            kt::add_measured_offset(pe, offset, r.data() + off);
            if (!to_residuals(*pe.e, r.data() + off, err)) return false;
            off += pe.e->n;
        }
        return true;
    }

    // CPU seconds of the threads batch() started (the calling thread's own are read by kt_fit)
    std::atomic<long long> *helper_cpu_ns = nullptr;

    // the residuals at a Levenberg-Marquardt run's start, with no crawl cap; then each experiment's
    // cap from its simulation's work there (kt_fit_options.crawl_factor), counted as at least
    // KT_CRAWL_FLOOR_PER_SAMPLE evaluations per sample
    bool start_residuals(const VectorXd &th, VectorXd &r, std::string &err, double crawl_factor) const
    {
        for (const kt::Prepared &pe : exps) pe.crawl_cap = 0;
        std::vector<long long> works;
        if (!residuals(th, r, err, true, &works)) return false;
        if (crawl_factor > 0)
            for (std::size_t i = 0; i < exps.size(); ++i)
                exps[i].crawl_cap = (long long)(crawl_factor * (double)std::max(works[i], KT_CRAWL_FLOOR_PER_SAMPLE * exps[i].e->n));
        return true;
    }

    // evaluate residuals at several points in parallel
    void batch(const std::vector<VectorXd> &pts, std::vector<VectorXd> &rs, std::vector<char> &ok,
               bool keep_raw = true) const
    {
        const std::size_t m = pts.size();
        rs.assign(m, VectorXd());
        ok.assign(m, 0);
        auto work = [&](std::size_t first, std::size_t stride) {
            for (std::size_t i = first; i < m; i += stride) {
                std::string e;
                ok[i] = residuals(pts[i], rs[i], e, keep_raw) ? 1 : 0;
            }
        };
        const std::size_t nt = std::min<std::size_t>((std::size_t)std::max(1, n_threads), m);
        if (nt <= 1) { work(0, 1); return; }
        auto helper = [&](std::size_t first, std::size_t stride) {
            work(first, stride);
            if (helper_cpu_ns) *helper_cpu_ns += thread_cpu_ns();
        };
        std::vector<std::thread> th;
        for (std::size_t i = 1; i < nt; ++i) th.emplace_back(helper, i, nt);
        work(0, nt);
        for (auto &x : th) x.join();
    }
};

struct Counters {
    long evaluations = 0;
    long jacobian_evaluations = 0; // of evaluations: the finite-difference Jacobians' columns
    int iterations = 0;
    long held_columns = 0; // Jacobian columns held at zero: no step near theta simulated (rescue_column)
    std::vector<double> history;
};

// column j of the Jacobian by a one-sided difference with this step; false where the point lies
// outside the box or fails to simulate
bool one_sided_column(const Problem &P, const VectorXd &th, const VectorXd &r, int j, double step, MatrixXd &J,
                      Counters &C)
{
    VectorXd a = th, ra;
    a[j] += step;
    if (a[j] > P.hi[j] || a[j] < P.lo[j]) return false;
    std::string err;
    ++C.evaluations;
    ++C.jacobian_evaluations;
    if (!P.residuals(a, ra, err, false)) return false;
    J.col(j) = (ra - r) / step;
    return true;
}

// Shorter steps tried, each side, where a column's step h failed both ways: a point at the edge of
// where the model simulates (a runaway, an integrator that gives up) has nearer neighbours that do
constexpr int KT_RESCUE_STEPS = 3;
constexpr double KT_RESCUE_SHRINK = 8.0;

// column j of the Jacobian where its difference step h failed to simulate both ways: by one-sided
// differences with steps h/8, h/64, ... (KT_RESCUE_STEPS of them, each side); where none simulates,
// held at zero (the fit then keeps parameter j where it is for this iteration, and its interval at
// the optimum is unbounded) and counted in C.held_columns
void rescue_column(const Problem &P, const VectorXd &th, const VectorXd &r, int j, double h, MatrixXd &J, Counters &C)
{
    double step = h;
    for (int i = 0; i < KT_RESCUE_STEPS; ++i) {
        step /= KT_RESCUE_SHRINK;
        if (one_sided_column(P, th, r, j, step, J, C) || one_sided_column(P, th, r, j, -step, J, C)) return;
    }
    J.col(j).setZero();
    ++C.held_columns;
}

// central (or forward) difference Jacobian at theta (r = residuals there). A central pair that
// would leave the box becomes a one-sided difference into it; a point that fails to simulate is
// replaced by the other side's, and a column neither side gives by rescue_column. offset_measured's
// points are not simulated where the outputs at theta are kept (RawOutputs): the same residuals, the
// same bits. False where every column is held (the fit cannot move).
bool jacobian(const Problem &P, const VectorXd &th, const VectorXd &r, double h, bool central, MatrixXd &J, Counters &C)
{
    const int k = (int)th.size();
    std::vector<VectorXd> pts;
    std::vector<double> steps;
    std::vector<char> two_sided;
    std::vector<int> col_of; // the column of each point
    for (int j = 0; j < k; ++j) {
        const bool both = central && th[j] + h <= P.hi[j] && th[j] - h >= P.lo[j];
        const double hj = th[j] + h > P.hi[j] ? -h : h; // one-sided: stay inside the box
        VectorXd a = th;
        a[j] += both ? h : hj;
        pts.push_back(a);
        col_of.push_back(j);
        steps.push_back(both ? h : hj);
        two_sided.push_back(both ? 1 : 0);
        if (both) {
            VectorXd b = th;
            b[j] -= h;
            pts.push_back(b);
            col_of.push_back(j);
        }
    }
    std::vector<VectorXd> rs(pts.size());
    std::vector<char> ok(pts.size(), 0);
    VectorXd before;
    const bool kept = P.offset_j >= 0 && P.raw && P.raw->get(th, P.n_res, before);
    std::vector<VectorXd> simulated;
    std::vector<std::size_t> simulated_at;
    for (std::size_t i = 0; i < pts.size(); ++i) {
        if (kept && col_of[i] == P.offset_j && P.offset_residuals(pts[i], before, rs[i])) {
            ok[i] = 1;
            continue;
        }
        simulated.push_back(pts[i]);
        simulated_at.push_back(i);
    }
    std::vector<VectorXd> srs;
    std::vector<char> sok;
    P.batch(simulated, srs, sok, false);
    for (std::size_t i = 0; i < simulated.size(); ++i) {
        rs[simulated_at[i]] = std::move(srs[i]);
        ok[simulated_at[i]] = sok[i];
    }
    C.evaluations += (long)simulated.size();
    C.jacobian_evaluations += (long)simulated.size();
    J.resize(r.size(), k);
    std::size_t at = 0;
    const long held_before = C.held_columns;
    for (int j = 0; j < k; ++j) {
        const double hj = steps[(std::size_t)j];
        if (two_sided[(std::size_t)j]) {
            if (ok[at] && ok[at + 1]) J.col(j) = (rs[at] - rs[at + 1]) / (2 * h);
            else if (ok[at]) J.col(j) = (rs[at] - r) / h;
            else if (ok[at + 1]) J.col(j) = (r - rs[at + 1]) / h;
            else rescue_column(P, th, r, j, h, J, C);
            at += 2;
        } else {
            if (ok[at]) J.col(j) = (rs[at] - r) / hj;
            else if (!one_sided_column(P, th, r, j, -hj, J, C)) rescue_column(P, th, r, j, h, J, C);
            at += 1;
        }
    }
    // every column held: the fit cannot move from theta
    return C.held_columns - held_before < k;
}

VectorXd clip(const Problem &P, const VectorXd &th) { return th.cwiseMax(P.lo).cwiseMin(P.hi); }

// the parameters held at a bound that the gradient g pushes them against (descent, -g, points out)
std::vector<char> active_bounds(const Problem &P, const VectorXd &th, const VectorXd &g)
{
    std::vector<char> held((std::size_t)th.size(), 0);
    for (int j = 0; j < th.size(); ++j)
        held[(std::size_t)j] = (th[j] <= P.lo[j] && g[j] > 0) || (th[j] >= P.hi[j] && g[j] < 0);
    return held;
}

// the Levenberg-Marquardt step of M d = -g with the parameters ``held`` at their bounds left out of
// the solve (their step 0). Taken where the step solved for all and clipped afterwards is too small
// to go on: that step moves the others as if the held ones had moved too, and where the held ones
// dominate it shrinks below xtol ("step small") far from the optimum
VectorXd bounded_step(MatrixXd M, VectorXd g, const std::vector<char> &held)
{
    for (int j = 0; j < g.size(); ++j) {
        if (!held[(std::size_t)j]) continue;
        M.row(j).setZero();
        M.col(j).setZero();
        M(j, j) = 1.0;
        g[j] = 0.0;
    }
    return M.ldlt().solve(-g);
}

// central_differences = 2: forward differences find the optimum's neighbourhood cheaply, but their
// O(h) error in a weakly determined direction (e.g. stiffness against mass along a resonance)
// leaves LM stopped short of the least-squares point; a few central-difference iterations from
// there reach it (docs/fit-convergence.md)
constexpr int KT_POLISH_CENTRAL = 2;

struct LMResult {
    VectorXd th;
    VectorXd r;
    double cost = std::numeric_limits<double>::infinity();
    int status = -1;
    std::string message;
    bool start_failed = false; // the start itself did not simulate (not a deadline)
    bool stage_cut = false;    // a horizon stage before the last stopped at the iteration limit
    // the finite-difference Jacobian at th, when the fit's last one was computed there (central or
    // forward as `central` says); empty otherwise. The statistics reuse it: the same bits as a new one
    MatrixXd J;
    bool central = false;
};

// J + (dr - J s) s^T / (s^T s): Broyden's rank-one update of the Jacobian after the step s, which
// changed the residuals by dr (the secant condition J s = dr holds afterwards; directions
// orthogonal to s keep their columns' action)
void broyden_update(MatrixXd &J, const VectorXd &s, const VectorXd &dr)
{
    const double ss = s.squaredNorm();
    if (!(ss > 0)) return;
    J += ((dr - J * s) / ss) * s.transpose();
}

// How many rank-one updates a Levenberg-Marquardt run may chain between finite-difference
// Jacobians: none with central differences (they polish the optimum), else the option's count.
int broyden_limit(const kt_fit_options &o) { return o.central_differences == 1 ? 0 : std::max(0, o.broyden_updates); }

// A secant-updated Jacobian is trusted for steps of at most this size in every scaled coordinate
// (log-scaled: a factor e; linear: one start magnitude); a longer step is taken only with a
// finite-difference Jacobian. Without the bound, steps along a poor update drove log-scaled
// stiffnesses to 1e-241, where their columns vanish for good (docs/speed.md, 2026-12-01).
constexpr double KT_SECANT_TRUST = 1.0;
// ... and updated again only after a step whose decrease was at least this share of the decrease
// its linear model predicted; after a poorer step the next Jacobian is a finite-difference one
constexpr double KT_SECANT_AGREEMENT = 0.25;

LMResult levenberg_marquardt(const Problem &P, const VectorXd &th0, const kt_fit_options &o, Counters &C, int start_no,
                             int stage = 0, int n_stages = 1)
{
    LMResult R;
    std::string err;
    VectorXd th = clip(P, th0), r;
    // a deadline passed (here, or inside a simulation): stopped like by the progress callback
    auto stopped_by_deadline = [&]() {
        if (!P.out_of_time()) return false;
        R.status = -2;
        R.message = P.limits->message();
        return true;
    };
    ++C.evaluations;
    if (P.limits && P.limits->expired() && stopped_by_deadline()) return R;
    if (!P.start_residuals(th, r, err, o.crawl_factor)) {
        if (!stopped_by_deadline()) {
            R.message = "the start fails to simulate: " + err;
            R.start_failed = true;
        }
        return R;
    }
    double cost = 0.5 * r.squaredNorm();
    C.history.push_back(cost);
    double lambda = 1e-3, nu = 2.0;
    R.status = 1;
    R.message = "maximum number of iterations reached";
    MatrixXd J;
    bool need_jacobian = true;
    // rank-one updates (broyden_update) since the last finite-difference Jacobian; a J that is one
    // never ends the fit: where it would (gradient small, step small, a small decrease, no
    // decrease), the finite-difference Jacobian is computed there and the iteration redone
    int updates = 0;
    const int max_updates = broyden_limit(o);
    bool j_at_th = false; // J is a finite-difference Jacobian at th
    for (int it = 0; it < o.max_iterations; ++it) {
        ++C.iterations;
        if (need_jacobian) {
            j_at_th = false;
            if (!jacobian(P, th, r, o.fd_step, o.central_differences != 0, J, C)) {
                if (!stopped_by_deadline()) {
                    R.status = -1;
                    R.message = "a Jacobian column failed to simulate";
                }
                break;
            }
            updates = 0;
            j_at_th = true;
        }
        need_jacobian = false;
        const MatrixXd A = J.transpose() * J;
        const VectorXd g = J.transpose() * r;
        // projected gradient: components pushing out of the box at an active bound do not count
        const std::vector<char> held = active_bounds(P, th, g);
        const bool any_held = std::find(held.begin(), held.end(), 1) != held.end();
        double gmax = 0;
        for (int j = 0; j < th.size(); ++j)
            if (!held[(std::size_t)j]) gmax = std::max(gmax, std::fabs(g[j]));
        // an iteration redone with a better J (not counted as one)
        auto redo_iteration = [&]() {
            --it;
            --C.iterations;
        };
        if (gmax <= o.gtol * std::max(cost, 1e-300)) {
            if (updates > 0) { need_jacobian = true; redo_iteration(); continue; }
            R.status = 0;
            R.message = "gradient small";
            break;
        }
        VectorXd dscale = A.diagonal().cwiseMax(1e-12 * std::max(1e-300, A.diagonal().maxCoeff()));
        bool accepted = false, converged = false, redo = false;
        double agreement = 0; // the accepted step's decrease over its predicted decrease (rho)
        VectorXd th_before = th, r_before = r;
        // (the loop can try several lambdas side by side, n_cand > 1; measured: it did not save
        // iterations on the full-model benchmark, so one candidate per try)
        for (int tries = 0; tries < 30; ++tries) {
            const double lams[2] = {lambda, lambda / 10.0};
            const int n_cand = 1;
            std::vector<VectorXd> cand, rs;
            std::vector<char> oks;
            std::vector<double> preds;
            bool small = false, far = false;
            for (int c = 0; c < n_cand; ++c) {
                MatrixXd M = A;
                M.diagonal() += lams[c] * dscale;
                VectorXd tn = clip(P, th + M.ldlt().solve(-g));
                VectorXd step = tn - th;
                const double xsmall = o.xtol * (th.norm() + o.xtol);
                if (c == 0 && step.norm() <= xsmall && any_held) {
                    tn = clip(P, th + bounded_step(M, g, held));
                    step = tn - th;
                }
                if (c == 0 && step.norm() <= xsmall) { small = true; break; }
                if (updates > 0 && step.lpNorm<Eigen::Infinity>() > KT_SECANT_TRUST) { far = true; break; }
                preds.push_back(-(g.dot(step) + 0.5 * step.dot(A * step)));
                cand.push_back(tn);
            }
            if ((small || far) && updates > 0) { need_jacobian = true; redo = true; break; }
            if (small) { converged = true; R.message = "step small"; break; }
            P.batch(cand, rs, oks);
            C.evaluations += (long)cand.size();
            if (P.out_of_time()) break;
            int best = -1;
            double cn = cost;
            for (int c = 0; c < (int)cand.size(); ++c) {
                if (!oks[(std::size_t)c]) continue;
                const double cc = 0.5 * rs[(std::size_t)c].squaredNorm();
                if (cc < cn) { cn = cc; best = c; }
            }
            if (best >= 0) {
                const double rho = (cost - cn) / std::max(preds[(std::size_t)best], 1e-300);
                const double rel = (cost - cn) / cost;
                agreement = rho;
                th = cand[(std::size_t)best];
                r = rs[(std::size_t)best];
                cost = cn;
                lambda = lams[best];
                C.history.push_back(cost);
                j_at_th = false;
                // shrink lambda fast on good steps: the weak directions of an ill-conditioned
                // problem move only once lambda * diag(J^T J) is below their curvature
                if (rho > 0.5) lambda /= 10.0;
                else if (rho > 0.25) lambda /= 3.0;
                else if (rho < 0.1) lambda *= 2.0;
                lambda = std::max(lambda, 1e-16);
                nu = 2.0;
                accepted = true;
                if (rel < o.ftol) { converged = true; R.message = "relative cost decrease small"; }
                const double s2 = 2.0 * cost / std::max(1, P.n_fitted - (int)th.size());
                if (!converged && o.stat_tol > 0 && cost * rel < o.stat_tol * s2) {
                    converged = true;
                    R.message = "cost decrease far below the residual variance";
                }
                // a small decrease along an updated J's step: go on with a finite-difference one
                if (converged && updates > 0) { converged = false; need_jacobian = true; }
                break;
            }
            // no decrease along an updated J's step: the trial's secant updates it once more (and
            // lambda grows), or, at the limit of updates, a finite-difference J (the same lambda)
            if (updates > 0) {
                if (updates < max_updates && oks[0]) {
                    broyden_update(J, cand[0] - th, rs[0] - r);
                    ++updates;
                    lambda *= nu;
                    nu *= 2.0;
                } else {
                    need_jacobian = true;
                }
                redo = true;
                break;
            }
            lambda *= nu;
            nu *= 2.0;
            if (lambda > 1e16) { converged = true; R.message = "no decrease found (lambda at its limit)"; break; }
        }
        if (stopped_by_deadline()) break;
        if (redo) { redo_iteration(); continue; }
        if (o.verbose)
            std::fprintf(stderr, "[kt_fit] start %d it %d cost %.6e lambda %.2e evals %ld\n", start_no, it, cost, lambda,
                         C.evaluations);
        if (o.progress && o.progress(o.progress_ctx, start_no, stage, n_stages, it, cost, C.evaluations) != 0) {
            R.status = -2;
            R.message = "stopped by the progress callback";
            break;
        }
        if (converged) { R.status = 0; break; }
        if (!accepted) { R.status = 0; R.message = "no decrease found"; break; }
        if (!need_jacobian && updates < max_updates && agreement >= KT_SECANT_AGREEMENT) {
            broyden_update(J, th - th_before, r - r_before);
            ++updates;
        } else {
            need_jacobian = true;
        }
    }
    R.th = th;
    R.r = r;
    R.cost = cost;
    if (j_at_th && updates == 0) {
        R.J = J;
        R.central = o.central_differences != 0;
    }
    return R;
}

// contiguous blocks per experiment for the robust covariance: enough for a stable spread of the
// score, few enough that each block is longer than a model error's correlation (docs/fit-convergence.md)
constexpr int KT_ROBUST_BLOCKS = 20;

// The covariance of theta from residuals that may be correlated in time (a model that misses the
// record leaves a smooth, not a white, residual): the sandwich A^+ (sum_b g_b g_b^T) A^+ of the
// scores g_b = J_b^T r_b of contiguous blocks of each experiment's samples (A = J^T J, A^+ its
// pseudo-inverse from the SVD), scaled by B/(B-1) for the scores' zero sum. Never narrower than
// the classic s^2 A^+, whose variances it keeps where they are larger. A parameter that enters a
// direction the data do not see at all (a zero singular value: an Iwan element that never slips)
// gets an infinite variance; the others keep theirs.
MatrixXd robust_covariance(const Problem &P, const MatrixXd &J, const VectorXd &r, const MatrixXd &V,
                           const VectorXd &sv, double s2)
{
    const int k = (int)J.cols();
    VectorXd inv2 = VectorXd::Zero(k);
    std::vector<char> unseen((std::size_t)k, 0);
    for (int i = 0; i < k; ++i) {
        if (sv[i] > sv[0] * 1e-14) { inv2[i] = 1.0 / (sv[i] * sv[i]); continue; }
        for (int j = 0; j < k; ++j)
            if (std::fabs(V(j, i)) > 1e-8) unseen[(std::size_t)j] = 1;
    }
    const MatrixXd Ainv = V * inv2.asDiagonal() * V.transpose();
    const MatrixXd classic = s2 * Ainv;
    MatrixXd meat = MatrixXd::Zero(k, k);
    int off = 0, blocks = 0;
    for (const kt::Prepared &pe : P.exps) {
        const int n = pe.e->n;
        const int nb = std::max(1, std::min(KT_ROBUST_BLOCKS, n / (4 * (k + 1))));
        for (int b = 0; b < nb; ++b) {
            const int a = (int)((long long)n * b / nb), z = (int)((long long)n * (b + 1) / nb);
            const VectorXd g = J.middleRows(off + a, z - a).transpose() * r.segment(off + a, z - a);
            meat += g * g.transpose();
            ++blocks;
        }
        off += n;
    }
    MatrixXd cov = blocks < 2 ? classic : MatrixXd(Ainv * meat * Ainv * ((double)blocks / (blocks - 1)));
    VectorXd widen = VectorXd::Ones(k);
    for (int j = 0; j < k; ++j)
        if (cov(j, j) > 0 && classic(j, j) > cov(j, j)) widen[j] = std::sqrt(classic(j, j) / cov(j, j));
    cov = widen.asDiagonal() * cov * widen.asDiagonal();
    for (int j = 0; j < k; ++j) {
        if (!unseen[(std::size_t)j] && cov(j, j) > 0) continue;
        const double v = unseen[(std::size_t)j] ? std::numeric_limits<double>::infinity() : classic(j, j);
        cov.row(j).setZero();
        cov.col(j).setZero();
        cov(j, j) = v;
    }
    return cov;
}

// a converged forward-difference result continued with central differences; kept if not worse
LMResult polish_with_central_differences(const Problem &P, const LMResult &R, const kt_fit_options &o, Counters &C,
                                         int start_no, int n_stages)
{
    kt_fit_options oc = o;
    oc.central_differences = 1;
    LMResult Rc = levenberg_marquardt(P, R.th, oc, C, start_no, n_stages - 1, n_stages);
    if (Rc.status == -2) return Rc;
    Rc.stage_cut = R.stage_cut; // the polish continues the last stage: the earlier ones are as they were
    return Rc.status >= 0 && Rc.cost <= R.cost ? Rc : R;
}

// One start through the horizon stages. A later stage begins at the earlier stage's optimum; where
// that point fails to simulate on the longer horizon (the part of the record it never saw drives it
// out of the model's range), the stage begins again at the start's own point.
LMResult fit_through_stages(const std::vector<Problem> &stages, const VectorXd &th_start, const kt_fit_options &o,
                            Counters &C, int start_no)
{
    const int n_stages = (int)stages.size();
    VectorXd th = th_start;
    LMResult R;
    bool stage_cut = false;
    for (int sg = 0; sg < n_stages; ++sg) {
        if (sg > 0 && R.status == 1) stage_cut = true;
        // stages before the last only bring the start near the optimum: a looser stop
        kt_fit_options os = o;
        if (sg < n_stages - 1) os.stat_tol = std::max(o.stat_tol, 0.1);
        if (os.central_differences == KT_POLISH_CENTRAL) os.central_differences = 0;
        R = levenberg_marquardt(stages[(std::size_t)sg], th, os, C, start_no, sg, n_stages);
        if (R.start_failed && sg > 0)
            R = levenberg_marquardt(stages[(std::size_t)sg], th_start, os, C, start_no, sg, n_stages);
        if (R.status < 0) break;
        th = R.th;
    }
    R.stage_cut = stage_cut;
    return R;
}

// A fit converges only where every stage did: one whose earlier horizon stage stopped at the
// iteration limit began its last stage elsewhere than a longer run would, and reports the limit
// (status 1) though its last stage converged.
LMResult reported(LMResult R)
{
    if (R.stage_cut && R.status == 0) {
        R.status = 1;
        R.message = "maximum number of iterations reached in an earlier stage (" + R.message + " in the last)";
    }
    return R;
}

template <class T> void put(T *dst, std::size_t i, T v) { if (dst) dst[i] = v; }

} // namespace

extern "C" {

void kt_fit_default_options(kt_fit_options *o)
{
    if (!o) return;
    std::memset(o, 0, sizeof *o);
    o->max_iterations = 100;
    o->ftol = 1e-10;
    o->xtol = 1e-9;
    o->gtol = 1e-12;
    o->fd_step = 1e-3;
    o->central_differences = KT_POLISH_CENTRAL;
    o->n_starts = 1;
    o->start_spread = 0.5;
    o->seed = 1;
    o->n_threads = 0;
    o->rtol = 0;
    o->singular_rel_tol = 1e-4;
    o->max_rel_std = 0.5;
    o->stat_tol = 1e-2;
    o->output_stride = 1;
    o->horizon_stages = 1;
    o->verbose = 0;
    o->progress = nullptr;
    o->progress_ctx = nullptr;
    o->continuous_input = 1;
    o->broyden_updates = 0;
    o->crawl_factor = 100.0;
}

int kt_fit(const kt_experiment *experiments, int n_exp, int k, const char *const *names, const double *lower,
           const double *upper, const double *start, const int *scaling, const kt_fit_options *options,
           kt_fit_result *res)
{
    const auto t0 = std::chrono::steady_clock::now();
    const long long cpu0 = thread_cpu_ns();
    std::string &err = kt::last_error;
    err.clear();
    try {
        if (!experiments || n_exp < 1) { err = "kt_fit: no experiments"; return -1; }
        if (k < 1 || !names || !start || !res) { err = "kt_fit: need k >= 1 names, start values and a result"; return -1; }
        kt_fit_options o;
        kt_fit_default_options(&o);
        if (options) o = *options;
        if (o.n_threads <= 0) o.n_threads = (int)std::max(1u, std::thread::hardware_concurrency());
        if (o.n_starts < 1) o.n_starts = 1;
        if (!(o.fd_step > 0)) o.fd_step = 1e-3;

        Problem P;
        P.n_threads = o.n_threads;
        std::atomic<long long> helper_cpu_ns{0};
        P.helper_cpu_ns = &helper_cpu_ns;
        kt::Limits limits;
        limits.monotonic = o.deadline_monotonic > 0 ? o.deadline_monotonic : 0.0;
        limits.cpu = o.deadline_cpu > 0 ? o.deadline_cpu : 0.0;
        if (o.deadline_thread_cpu > 0) {
            if (pthread_getcpuclockid(pthread_self(), &limits.thread_clock) != 0) {
                err = "kt_fit: deadline_thread_cpu: this thread's CPU clock cannot be read";
                return -1;
            }
            limits.thread_cpu = o.deadline_thread_cpu;
        }
        limits.work_cap = o.max_rhs_evaluations > 0 ? o.max_rhs_evaluations : 0.0;
        P.limits = &limits; // with no deadline and no cap, it only counts the fit's work
        P.rtol_override = o.rtol;
        P.exps.resize((std::size_t)n_exp);
        for (int i = 0; i < n_exp; ++i) {
            std::string e;
            if (!experiments[i].measured) { err = "experiment " + std::to_string(i) + ": no measured samples"; return -1; }
            if (!kt::prepare(experiments[i], 0, nullptr, P.exps[(std::size_t)i], e)) {
                err = "experiment " + std::to_string(i) + ": " + e;
                return -1;
            }
            P.exps[(std::size_t)i].stride = std::max(1, o.output_stride);
            P.exps[(std::size_t)i].continuous_input = o.continuous_input != 0;
            P.exps[(std::size_t)i].limits = P.limits;
            P.n_res += experiments[i].n;
            P.n_fitted += fitted_samples(experiments[i]);
        }
        // horizon stages: the same problem on the first part of each non-periodic record
        const int n_stages = std::max(1, o.horizon_stages);
        std::vector<std::vector<kt_experiment>> stage_exps((std::size_t)n_stages);
        std::vector<Problem> stages((std::size_t)n_stages);
        P.lo.resize(k);
        P.hi.resize(k);
        VectorXd th0(k);
        for (int j = 0; j < k; ++j) {
            const int idx = kt::parameter_index(names[j]);
            if (idx < 0) { err = std::string("parameter '") + (names[j] ? names[j] : "(null)") + "': no such parameter"; return -1; }
            if (kt::parameter_table()[(std::size_t)idx].kind == KT_PAR_SWITCH) { err = std::string("parameter '") + names[j] + "' is a switch and cannot be fitted"; return -1; }
            for (int i = 0; i < j; ++i)
                if (P.par[(std::size_t)i] == idx) { err = std::string("parameter '") + names[j] + "' given twice"; return -1; }
            P.par.push_back(idx);
            if (std::strcmp(names[j], "offset_measured") == 0) P.offset_j = j;
            const double lo = lower ? lower[j] : -HUGE_VAL, hi = upper ? upper[j] : HUGE_VAL, s = start[j];
            if (!(lo <= s && s <= hi) || !std::isfinite(s)) {
                char b[256];
                std::snprintf(b, sizeof b, "parameter '%s': start %g is outside its bounds [%g, %g]", names[j], s, lo, hi);
                err = b;
                return -1;
            }
            int sc = scaling ? scaling[j] : KT_SCALE_AUTO;
            const bool positive = lo > 0 || (lo >= 0 && s > 0), negative = hi < 0 || (hi <= 0 && s < 0);
            if (sc == KT_SCALE_AUTO) sc = (positive || negative) && s != 0 ? KT_SCALE_LOG : KT_SCALE_LINEAR;
            if (sc == KT_SCALE_LOG && !((positive || negative) && s != 0)) {
                err = std::string("parameter '") + names[j] + "': log scaling needs a start and bounds of one sign";
                return -1;
            }
            P.log_scale.push_back(sc == KT_SCALE_LOG);
            P.sign.push_back(s < 0 ? -1.0 : 1.0);
            P.scale.push_back(s != 0 ? std::fabs(s) : 1.0);
            if (sc == KT_SCALE_LOG) {
                // theta increases with |p|
                const double a = std::fabs(lo), b = std::fabs(hi);
                const double mn = positive ? a : b, mx = positive ? b : a;
                P.lo[j] = mn > 0 ? std::log(mn) : -HUGE_VAL;
                P.hi[j] = std::isfinite(mx) ? std::log(mx) : HUGE_VAL;
            } else {
                P.lo[j] = lo / P.scale.back();
                P.hi[j] = hi / P.scale.back();
            }
            th0[j] = P.to_theta(j, s);
        }
        if (P.n_fitted <= k) { err = "kt_fit: fewer residuals than parameters"; return -1; }
        if (P.offset_j >= 0) P.raw = std::make_shared<RawOutputs>();
        for (int sg = 0; sg < n_stages; ++sg) {
            Problem &Q = stages[(std::size_t)sg];
            Q = P;
            if (sg == n_stages - 1) break;
            const double frac = std::ldexp(1.0, -(n_stages - 1 - sg));
            auto &ex = stage_exps[(std::size_t)sg];
            ex.assign(experiments, experiments + n_exp);
            Q.n_res = Q.n_fitted = 0;
            for (int i = 0; i < n_exp; ++i) {
                kt_experiment &x = ex[(std::size_t)i];
                if (x.periodic_samples == 0) x.n = std::max(std::min(x.n, k + 2), (int)std::ceil(x.n * frac));
                Q.exps[(std::size_t)i].e = &x;
                Q.n_res += x.n;
                Q.n_fitted += fitted_samples(x);
            }
        }

        // several starts: the given one, then random ones
        Counters C;
        std::mt19937_64 rng(o.seed);
        std::uniform_real_distribution<double> U(0.0, 1.0);
        LMResult best;
        int best_start = -1;
        for (int st = 0; st < o.n_starts; ++st) {
            VectorXd th = th0;
            if (st > 0)
                for (int j = 0; j < k; ++j) {
                    const double a = P.lo[j], b = P.hi[j];
                    if (std::isfinite(a) && std::isfinite(b)) th[j] = a + (b - a) * U(rng);
                    else th[j] = th0[j] + o.start_spread * (2 * U(rng) - 1);
                }
            LMResult R = fit_through_stages(stages, th, o, C, st);
            if (R.status == -2) { err = "kt_fit: " + R.message; return -1; }
            if (R.status >= 0 && o.central_differences == KT_POLISH_CENTRAL) {
                R = polish_with_central_differences(stages.back(), R, o, C, st, n_stages);
                if (R.status == -2) { err = "kt_fit: " + R.message; return -1; }
            }
            R = reported(R);
            if (R.status >= 0 && R.cost < best.cost) { best = R; best_start = st; }
            else if (best_start < 0 && st == o.n_starts - 1 && best.th.size() == 0) best = R;
        }
        if (best_start < 0) { err = "kt_fit: every start failed: " + best.message; return -1; }

        // statistics at the optimum: a fresh Jacobian there
        MatrixXd J;
        const bool central = o.central_differences != 0;
        if (best.J.rows() == P.n_res && best.J.cols() == k && best.central == central) J = best.J;
        else if (!jacobian(P, best.th, best.r, o.fd_step, central, J, C)) {
            err = P.out_of_time() ? "kt_fit: " + P.limits->message() : "kt_fit: the Jacobian at the optimum failed to simulate";
            return -1;
        }
        const int N = P.n_fitted, dof = N - k;
        const double ssr = best.r.squaredNorm();
        const double s2 = ssr / dof;
        Eigen::JacobiSVD<MatrixXd> svd(J, Eigen::ComputeThinU | Eigen::ComputeThinV);
        const VectorXd sv = svd.singularValues();
        const MatrixXd V = svd.matrixV();
        const double smax = sv.size() ? sv[0] : 0.0;
        // covariance in theta (robust_covariance); in p: D cov D
        const MatrixXd cov_th = robust_covariance(P, J, best.r, V, sv, s2);
        VectorXd D(k);
        for (int j = 0; j < k; ++j) D[j] = P.dp_dtheta(j, best.th[j]);
        MatrixXd cov = D.asDiagonal() * cov_th * D.asDiagonal();
        const double tq = t_quantile_975(dof);

        res->cost = best.cost;
        res->rms = std::sqrt(ssr / N);
        res->sigma2 = s2;
        res->condition = sv[k - 1] > 0 ? smax / sv[k - 1] : std::numeric_limits<double>::infinity();
        res->n_residuals = N;
        res->dof = dof;
        res->evaluations = (int)C.evaluations;
        res->jacobian_evaluations = (int)C.jacobian_evaluations;
        res->iterations = C.iterations;
        res->best_start = best_start;
        res->status = best.status;
        std::string message = best.message;
        if (C.held_columns > 0)
            message += " (a Jacobian column was held at zero " + std::to_string(C.held_columns) +
                       " time(s): no step near the point simulated or stayed within the bounds)";
        std::snprintf(res->message, sizeof res->message, "%s", message.c_str());
        res->cost_history_length = 0;
        for (double c : C.history)
            if (res->cost_history && res->cost_history_length < res->cost_history_capacity)
                res->cost_history[res->cost_history_length++] = c;
        for (int j = 0; j < k; ++j) {
            const double p = P.to_p(j, best.th[j]);
            const double se = std::sqrt(std::max(0.0, cov(j, j)));
            put(res->values, (std::size_t)j, p);
            put(res->std_error, (std::size_t)j, se);
            put(res->ci_low, (std::size_t)j, p - tq * se);
            put(res->ci_high, (std::size_t)j, p + tq * se);
            put(res->singular_values, (std::size_t)j, sv[j]);
            for (int i = 0; i < k; ++i) {
                put(res->covariance, (std::size_t)(j * k + i), cov(j, i));
                const double d = std::sqrt(cov(j, j) * cov(i, i));
                put(res->correlation, (std::size_t)(j * k + i), d > 0 ? cov(j, i) / d : (i == j ? 1.0 : 0.0));
                put(res->singular_vectors, (std::size_t)(j * k + i), V(j, i));
            }
            put(res->unidentifiable, (std::size_t)j, 0);
        }
        // identifiability: directions of the scaled parameters that the data hardly see
        std::string report;
        const double s = std::sqrt(s2);
        for (int i = 0; i < k; ++i) {
            const double rel = smax > 0 ? sv[i] / smax : 0.0;
            const double sd = sv[i] > 0 ? s / sv[i] : std::numeric_limits<double>::infinity();
            const bool flag = rel < o.singular_rel_tol || sd > o.max_rel_std;
            put(res->direction_flags, (std::size_t)i, flag ? 1 : 0);
            if (!flag) continue;
            char line[512];
            int used = std::snprintf(line, sizeof line, "direction %d: sigma/sigma_max = %.3g, std %.3g:", i, rel, sd);
            // parameters dominating the direction, largest first
            std::vector<int> order(k);
            for (int j = 0; j < k; ++j) order[(std::size_t)j] = j;
            std::sort(order.begin(), order.end(), [&](int a, int b) { return std::fabs(V(a, i)) > std::fabs(V(b, i)); });
            for (int j : order) {
                if (V(j, i) * V(j, i) < 0.05) break;
                if (V(j, i) * V(j, i) >= 0.1) put(res->unidentifiable, (std::size_t)j, 1);
                if (used < (int)sizeof line)
                    used += std::snprintf(line + used, sizeof line - (std::size_t)used, " %+.3f %s%s", V(j, i),
                                          P.log_scale[(std::size_t)j] ? "log " : "", names[j]);
            }
            report += line;
            report += "\n";
        }
        std::snprintf(res->report, sizeof res->report, "%s", report.c_str());
        res->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        res->cpu_seconds = 1e-9 * (double)(thread_cpu_ns() - cpu0 + helper_cpu_ns.load());
        res->rhs_evaluations = limits.work.load();
        return best.status;
    } catch (const std::exception &ex) {
        err = std::string("kt_fit: ") + ex.what();
        return -1;
    }
}

} // extern "C"
