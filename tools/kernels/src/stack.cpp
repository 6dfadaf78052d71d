#include "stack.hpp"

#include <algorithm>
#include <stdexcept>
#include <thread>

namespace dynid {
namespace {
// A velocity this close to zero is zero for the sign of Coulomb friction (dynid.robot.regressors.friction).
constexpr double kVelocityFloor = 1e-9;
}  // namespace

Stack::Stack(Chain chain, StackPlan plan) : chain_(std::move(chain)), plan_(std::move(plan)) {
    const StackPlan& P = plan_;
    const int nb = chain_.n_bodies();
    if (P.inertial0 < 0 || P.inertial0 + 10 * nb > P.columns) throw std::invalid_argument("stack: inertial span outside the columns");
    if (static_cast<int>(P.inertial.size()) != P.rows) throw std::invalid_argument("stack: one inertial term list per row");
    auto check_row = [&](int row) { if (row < 0 || row >= P.rows) throw std::invalid_argument("stack: row out of range"); };
    auto check_col = [&](int col, int width) {
        if (col < 0 || col + width > P.columns) throw std::invalid_argument("stack: column out of range");
    };
    for (const auto& terms : P.inertial)
        for (const Term& t : terms)
            if (t.index < 0 || t.index >= chain_.nv()) throw std::invalid_argument("stack: regressor row out of range");
    for (const auto& c : P.constants) { check_row(c.row); check_col(c.column, 1); }
    for (const auto& m : P.ft) check_row(m.row);
    for (const auto& c : P.friction) {
        check_col(c.column, 4);
        for (const Term& t : c.shares) check_row(t.index);
        for (const Term& t : c.velocity)
            if (t.index < 0 || t.index >= chain_.n_joints_configured()) throw std::invalid_argument("stack: velocity column out of range");
    }
    for (const auto* list : {&P.inputs, &P.torques})
        for (const auto& u : *list) {
            if (u.column >= 0) check_col(u.column, 1);
            for (const Term& t : u.shares) check_row(t.index);
        }
}

void Stack::fill(const StackInputs& in, const StackOutput& out, long begin, long end, int threads) const {
    const long n = end - begin;
    threads = static_cast<int>(std::max<long>(1, std::min<long>(threads, n / 256)));
    if (threads <= 1) return fill_range(in, out, begin, end);
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) {
        const long lo = begin + n * t / threads, hi = begin + n * (t + 1) / threads;
        pool.emplace_back([this, &in, &out, lo, hi] { fill_range(in, out, lo, hi); });
    }
    for (auto& th : pool) th.join();
}

void Stack::fill_range(const StackInputs& in, const StackOutput& out, long begin, long end) const {
    const StackPlan& P = plan_;
    const int r = P.rows, p = P.columns, nv = chain_.nv(), width = 10 * chain_.n_bodies();
    ChainState state(chain_.joints().size());
    std::vector<double> Y(static_cast<size_t>(nv) * width), A(static_cast<size_t>(r) * p), b(r);
    for (long k = begin; k < end; ++k) {
        const long nq = in.n_joints;
        const double* dq = in.dq + k * nq;
        chain_.regressor(in.q + k * nq, dq, in.ddq + k * nq, in.gravity ? in.gravity + 3 * k : nullptr, state,
                         Y.data(), width);
        std::fill(A.begin(), A.end(), 0.0);
        std::fill(b.begin(), b.end(), 0.0);
        for (const auto& m : P.ft) b[m.row] = in.ft[k * in.n_ft + m.column];
        for (int row = 0; row < r; ++row) {
            double* a = A.data() + static_cast<size_t>(row) * p + P.inertial0;
            for (const Term& t : P.inertial[row]) {
                const double* y = Y.data() + static_cast<size_t>(t.index) * width;
                for (int c = 0; c < width; ++c) a[c] += t.coef * y[c];
            }
            if (in.payload && !P.inertial[row].empty()) {
                double known = 0.0;
                for (int c = 0; c < width; ++c) known += a[c] * in.payload[c];
                b[row] -= known;
            }
        }
        for (const auto& c : P.constants) A[static_cast<size_t>(c.row) * p + c.column] = c.value;
        for (const auto& c : P.friction) {
            double v = 0.0, scale = 0.0;
            for (const Term& t : c.velocity) {
                v += t.coef * dq[t.index];
                scale += std::abs(t.coef) * std::abs(dq[t.index]);
            }
            // a coupled motor's velocity that cancels is exactly 0 (dynid.robot.regressors.stack.motor_velocities)
            if (c.velocity.size() > 1 && std::abs(v) <= 1e-12 * scale) v = 0.0;
            const double f[4] = {v > kVelocityFloor ? 1.0 : 0.0, v < -kVelocityFloor ? -1.0 : 0.0, std::max(v, 0.0),
                                 std::min(v, 0.0)};
            for (const Term& t : c.shares) {
                double* a = A.data() + static_cast<size_t>(t.index) * p + c.column;
                for (int j = 0; j < 4; ++j) a[j] = t.coef * f[j];
            }
        }
        for (const auto& u : P.torques) {
            const double x = in.torques[k * in.n_torques + u.source];
            for (const Term& t : u.shares) b[t.index] += t.coef * x;
        }
        for (const auto& u : P.inputs) {
            const double x = in.inputs[k * in.n_inputs + u.source];
            for (const Term& t : u.shares) {
                if (u.column >= 0)
                    A[static_cast<size_t>(t.index) * p + u.column] = t.coef * x;
                else
                    b[t.index] += t.coef * x;
            }
        }
        if (out.phi) {  // residuals only: b − A Φ per row, the rows built once for every Φ
            for (int m = 0; m < out.n_phi; ++m) {
                const double* phi = out.phi + static_cast<size_t>(m) * p;
                for (int row = 0; row < r; ++row) {
                    const double* a = A.data() + static_cast<size_t>(row) * p;
                    double dot = 0.0;
                    for (int c = 0; c < p; ++c) dot += a[c] * phi[c];
                    out.e[m * out.e_stride + k * r + row] = b[row] - dot;
                }
            }
            continue;
        }
        // out, weighted
        const double* w = in.weights ? in.weights + k * r : nullptr;
        for (int row = 0; row < r; ++row) {
            const double wr = w ? w[row] : 1.0;
            const double* a = A.data() + static_cast<size_t>(row) * p;
            double* o = out.A + k * out.sA0 + row * out.sA1;
            if (out.sA2 == 1) {
                if (w) for (int c = 0; c < p; ++c) o[c] = a[c] * wr;
                else std::copy(a, a + p, o);
            } else {
                for (int c = 0; c < p; ++c) o[c * out.sA2] = w ? a[c] * wr : a[c];
            }
            out.b[k * out.sb0 + row * out.sb1] = w ? b[row] * wr : b[row];
        }
    }
}

}  // namespace dynid
