// rt_bench: time per sample of the full real-time core (filter, RNEA prediction, residuals, T², detector), of the
// core running the momentum observer instead (momentum terms, observer, band, T², detector, τ_ext), of the combined
// detector (both, where the file carries its κ), and in the same run Pinocchio's rnea on the same chain (built from the same coefficient file: any robot dynid exports).
//   rt_bench [COEF_FILE] [--samples N]
// Each call is timed alone (steady_clock; its own overhead is reported and not subtracted). The heap allocations
// the core's steps make are counted (alloc_count.cpp) and must be zero: exit 3 otherwise.
#include "rt_monitor/core.hpp"
#include "rt_monitor/run_stats.hpp"

#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody/data.hpp>
#include <pinocchio/multibody/model.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

using namespace dynid::rt;
using Clock = std::chrono::steady_clock;

namespace {

pinocchio::Model pinocchio_chain(const Coefficients& c) {
    // Fixed (F/T split) bodies are appended to their parent's joint, so the chain keeps its n_joints joints.
    pinocchio::Model m;
    m.gravity.linear(c.gravity);
    std::vector<pinocchio::JointIndex> joint_of(c.n_bodies);
    std::vector<pinocchio::SE3> offset(c.n_bodies, pinocchio::SE3::Identity());  // body frame in its joint frame
    for (int i = 0; i < c.n_bodies; ++i) {
        const int p = c.parent[i];
        const pinocchio::JointIndex pj = p < 0 ? 0 : joint_of[p];
        const pinocchio::SE3 parent_offset = p < 0 ? pinocchio::SE3::Identity() : offset[p];
        const pinocchio::SE3 placement = parent_offset * pinocchio::SE3(c.rotation[i], c.translation[i]);
        Eigen::Matrix<double, 10, 1> phi;
        phi << c.mass[i], c.first_moment[i], c.inertia[i](0, 0), c.inertia[i](0, 1), c.inertia[i](1, 1),
            c.inertia[i](0, 2), c.inertia[i](1, 2), c.inertia[i](2, 2);
        const auto inertia = pinocchio::Inertia::FromDynamicParameters(phi);
        if (c.joint_type[i] == JointType::kFixed) {
            joint_of[i] = pj;
            offset[i] = placement;
            m.appendBodyToJoint(pj, inertia, placement);
        } else {
            const std::string name = c.joint_names[c.joint_index[i]];
            joint_of[i] = c.joint_type[i] == JointType::kPrismatic
                              ? m.addJoint(pj, pinocchio::JointModelPrismaticUnaligned(c.axis[i]), placement, name)
                              : m.addJoint(pj, pinocchio::JointModelRevoluteUnaligned(c.axis[i]), placement, name);
            m.appendBodyToJoint(joint_of[i], inertia, pinocchio::SE3::Identity());
        }
    }
    return m;
}

struct Stats {
    double median, p999, max, mean;
};

Stats stats(std::vector<double> ns) {
    std::sort(ns.begin(), ns.end());
    double sum = 0;
    for (double x : ns) sum += x;
    auto at = [&](double f) { return ns[std::min(ns.size() - 1, size_t(f * double(ns.size())))]; };
    return {at(0.5), at(0.999), ns.back(), sum / double(ns.size())};
}

}  // namespace

int main(int argc, char** argv) {
    std::string path = RT_BENCH_COEF;
    long n = 200000;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--samples" && i + 1 < argc) n = std::stol(argv[++i]);
        else path = a;
    }
    auto c = std::make_unique<Coefficients>();
    const LoadResult r = load_coefficients(path, "", *c);
    if (!r) {
        std::fprintf(stderr, "rt_bench: refused: %s\n", r.message.c_str());
        return kExitBase + int(r.error);
    }
    const int nj = c->n_joints, no = c->n_outputs;
    // A smooth random motion and outputs near the model's, so every branch (both signs, gating) is taken.
    std::mt19937_64 rng(1);
    std::normal_distribution<double> g(0.0, 1.0);
    std::vector<double> Q(size_t(n) * nj), Y(size_t(n) * no), V(size_t(n) * nj), A(size_t(n) * nj);
    std::vector<double> freq(nj), phase(nj);
    for (int j = 0; j < nj; ++j) freq[j] = 0.3 + 0.2 * j, phase[j] = g(rng);
    for (long k = 0; k < n; ++k) {
        const double t = 1e-3 * double(k);
        for (int j = 0; j < nj; ++j) {
            Q[k * nj + j] = 0.5 * std::sin(freq[j] * t + phase[j]) + 1e-4 * g(rng);
            V[k * nj + j] = 0.5 * freq[j] * std::cos(freq[j] * t + phase[j]);
            A[k * nj + j] = -0.5 * freq[j] * freq[j] * std::sin(freq[j] * t + phase[j]);
        }
        for (int i = 0; i < no; ++i) Y[k * no + i] = (i < 6 ? 1.0 : 0.05) * g(rng);
    }

    // A file without the observer (a CAD export: no data to calibrate it on) gets one for timing only: the file's
    // filter window as the q̇ estimator (least-squares slope), unit variances, thresholds no sample reaches.
    const bool placeholder_observer = !c->has_observer();
    if (placeholder_observer) {
        const int w = std::max(3, c->window);
        c->velocity_window = w;
        c->observer_bandwidth = 15.0;
        double centre = 0.5 * (w - 1), s2 = 0;
        for (int i = 0; i < w; ++i) s2 += (i - centre) * (i - centre);
        for (int i = 0; i < w; ++i) c->velocity_filter[i] = (i - centre) / (s2 * c->sample_period);
        for (int i = 0; i < no; ++i) c->observer_variance[size_t(i)] = 1.0;
        c->observer_threshold = c->observer_rest_threshold = 1e300;
        for (auto& t : c->observer_ft_threshold) t = 1e300;
    }
    // Nor the combined detector's κ (calibrated on paired residuals of data): one for timing only, so that every
    // file's combined core, what `dynid export` selects by default, is timed.
    const bool placeholder_combined = !c->has_combined();
    if (placeholder_combined) c->combined_scale = 2.0;
    auto core = std::make_unique<Core>(*c);
    core->set_residual(Residual::kAcceleration);  // each residual timed on its own, whatever the file selects
    auto observer = std::make_unique<Core>(*c);
    auto combined = std::make_unique<Core>(*c);
    const bool combines = combined->set_residual(Residual::kCombined);  // both residuals
    if (!observer->set_residual(Residual::kMomentum)) {
        std::fprintf(stderr, "rt_bench: the momentum observer of %s does not start\n", path.c_str());
        return 2;
    }
    pinocchio::Model pm = pinocchio_chain(*c);
    pinocchio::Data pd(pm);
    Eigen::VectorXd q(pm.nq), v(pm.nv), a(pm.nv);
    // Pinocchio numbers its joints in body order; the core, in the configuration's (a chain re-rooted at a sole runs
    // some joints backwards): where each of the core's joints sits in Pinocchio's q.
    std::vector<int> at(static_cast<size_t>(nj));
    for (int j = 0; j < nj; ++j) at[size_t(j)] = pm.joints[pm.getJointId(c->joint_names[j])].idx_q();

    std::vector<double> t_core(static_cast<size_t>(n)), t_rnea(static_cast<size_t>(n)), t_clock(static_cast<size_t>(n));
    std::vector<double> t_obs(static_cast<size_t>(n)), t_comb(static_cast<size_t>(n));
    volatile double sink = 0;
    long long core_allocations = 0;  // counted outside the timed spans
    const auto ns = [](Clock::time_point from, Clock::time_point to) {
        return std::chrono::duration<double, std::nano>(to - from).count();
    };
    // One core's step on sample k, timed into times[k]; its allocations counted apart from the timing.
    const auto timed_step = [&](Core& which, long k, std::vector<double>& times) {
        const long long before = allocations();
        const auto t0 = Clock::now();
        const Output& o = which.step(&Q[k * nj], &Y[k * no]);
        const auto t1 = Clock::now();
        core_allocations += allocations() - before;
        sink = sink + o.p.t2;
        times[size_t(k)] = ns(t0, t1);
    };
    for (long k = 0; k < n; ++k) {  // interleaved, so every one sees the same machine state
        timed_step(*core, k, t_core);
        for (int j = 0; j < nj; ++j) q[at[j]] = Q[k * nj + j], v[at[j]] = V[k * nj + j], a[at[j]] = A[k * nj + j];
        const auto t0 = Clock::now();
        pinocchio::rnea(pm, pd, q, v, a);
        const auto t1 = Clock::now();
        sink = sink + pd.tau[0];
        t_rnea[size_t(k)] = ns(t0, t1);
        t_clock[size_t(k)] = ns(t1, Clock::now());  // two reads back to back: the timer's own cost, in every span
        timed_step(*observer, k, t_obs);
        if (combines) timed_step(*combined, k, t_comb);
    }
    // Same chain, same answer: the core's joint torques against Pinocchio's on every 1000th state.
    double worst = 0, worst_p = 0, worst_beta = 0;
    for (long k = 0; k < n; k += 1000) {
        VecJ qq = VecJ::Zero(), vv = VecJ::Zero(), aa = VecJ::Zero();
        for (int j = 0; j < nj; ++j)
            qq[j] = q[at[j]] = Q[k * nj + j], vv[j] = v[at[j]] = V[k * nj + j], aa[j] = a[at[j]] = A[k * nj + j];
        Prediction p;
        core->predict(qq, vv, aa, VecO::Zero(), p);
        pinocchio::rnea(pm, pd, q, v, a);
        for (int j = 0; j < nj; ++j)
            worst = std::max(worst, std::abs(p.tau[j] - pd.tau[at[j]]) / (1e-12 + pd.tau.cwiseAbs().maxCoeff()));
        // The observer's momentum terms: p = M q̇ and β = Cᵀq̇ − g against Pinocchio's crba, Coriolis matrix, gravity.
        MomentumTerms m;
        momentum_terms(*c, qq.data(), vv.data(), m);
        pinocchio::crba(pm, pd, q);
        pd.M.triangularView<Eigen::StrictlyLower>() = pd.M.transpose().triangularView<Eigen::StrictlyLower>();
        const Eigen::VectorXd mv = pd.M * v;
        const Eigen::VectorXd beta = pinocchio::computeCoriolisMatrix(pm, pd, q, v).transpose() * v -
                                     pinocchio::computeGeneralizedGravity(pm, pd, q);
        for (int j = 0; j < nj; ++j) {
            worst_p = std::max(worst_p, std::abs(m.p[j] - mv[at[j]]) / (1e-12 + mv.cwiseAbs().maxCoeff()));
            worst_beta = std::max(worst_beta, std::abs(m.beta[j] - beta[at[j]]) / (1e-12 + beta.cwiseAbs().maxCoeff()));
        }
    }
    const long warm = std::min<long>(n / 10, 1000);  // first calls: cold caches, filter warm-up
    for (std::vector<double>* t : {&t_core, &t_rnea, &t_clock, &t_obs, &t_comb}) t->erase(t->begin(), t->begin() + warm);
    const Stats sc = stats(t_core), sr = stats(t_rnea), sk = stats(t_clock), so = stats(t_obs), sb = stats(t_comb);
    std::printf("rt_bench: %s, %d joints, %d outputs, filter window %d; %ld samples timed one by one\n",
                c->robot_name.c_str(), nj, no, c->window, n - warm);
    std::printf("  full core step       median %7.1f ns  p99.9 %7.1f ns  max %9.1f ns  mean %7.1f ns\n", sc.median,
                sc.p999, sc.max, sc.mean);
    std::printf("  observer core step   median %7.1f ns  p99.9 %7.1f ns  max %9.1f ns  mean %7.1f ns%s\n", so.median,
                so.p999, so.max, so.mean, placeholder_observer ? " (placeholder gains: the file has none)" : "");
    if (combines)
        std::printf("  combined core step   median %7.1f ns  p99.9 %7.1f ns  max %9.1f ns  mean %7.1f ns%s\n", sb.median,
                    sb.p999, sb.max, sb.mean, placeholder_combined ? " (placeholder κ: the file has none)" : "");
    std::printf("  pinocchio::rnea      median %7.1f ns  p99.9 %7.1f ns  max %9.1f ns  mean %7.1f ns\n", sr.median,
                sr.p999, sr.max, sr.mean);
    std::printf("  timer overhead       median %7.1f ns (included in both)\n", sk.median);
    std::printf("  ratio core / rnea (medians): %.2f\n", sc.median / sr.median);
    std::printf("  ratio observer core / rnea (medians): %.2f\n", so.median / sr.median);
    if (combines) std::printf("  ratio combined core / rnea (medians): %.2f\n", sb.median / sr.median);
    const double selected = c->residual == Residual::kMomentum   ? so.median
                            : c->residual == Residual::kCombined ? sb.median
                                                                 : sc.median;
    std::printf("  the file selects the %s residuals: core / rnea %.2f\n",
                c->residual == Residual::kMomentum   ? "momentum-observer"
                : c->residual == Residual::kCombined ? "combined (momentum-observer and acceleration)"
                                                     : "acceleration",
                selected / sr.median);
    std::printf("  joint torques, core vs Pinocchio: max relative difference %.2e\n", worst);
    std::printf("  momentum M q̇ and Cᵀq̇ − g, core vs Pinocchio: max relative difference %.2e, %.2e\n", worst_p,
                worst_beta);
    std::printf("  heap allocations in %ld core steps: %lld (the process's, set-up included: %lld)%s\n", (combines ? 3 : 2) * n,
                core_allocations, allocations(), allocations_count_malloc() ? "" : " (operator new only)");
    if (core_allocations != 0) return 3;
    return sink == 12345.678 ? 1 : 0;
}
