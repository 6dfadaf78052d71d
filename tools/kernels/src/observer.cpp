// The momentum observer's per-sample products (dynid.detect.momentum.momentum_terms) and its first-order filter
// (dynid.detect.momentum.first_order) over whole runs, on Pinocchio's C++ API: p = M q̇ (RNEA at rest with q̇ as the
// acceleration, minus g) and Cᵀq̇ − g (computeCoriolisMatrix, computeGeneralizedGravity), as the reference computes
// them through Pinocchio's Python bindings one sample at a time.
#include "algorithms.hpp"
#include "bindings.hpp"
#include "pinocchio_model.hpp"

#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>

#include <cmath>
#include <optional>
#include <tuple>
#include <vector>

namespace dynid {

namespace {

class MomentumTerms {
public:
    explicit MomentumTerms(const std::string& serialized) : model_(load_model(serialized)) {}
    int nq() const { return model_.nq; }
    int nv() const { return model_.nv; }

    void compute(CArray2 Q, CArray2 V, std::optional<CArray2> gravity, CArray2Out P, CArray2Out B) const {
        const long n = rows_of(Q, "q", model_.nq);
        shape2(V, n, model_.nv, "v");
        if (gravity) shape2(*gravity, n, 3, "gravity");
        if (P.shape(0) != static_cast<size_t>(n) || P.shape(1) != static_cast<size_t>(model_.nv) ||
            B.shape(0) != static_cast<size_t>(n) || B.shape(1) != static_cast<size_t>(model_.nv))
            throw std::invalid_argument("p and beta must be (N, nv)");
        nb::gil_scoped_release release;
        pinocchio::Model m = model_;  // its own copy: gravity changes per sample for a tilting base
        pinocchio::Data data(m);
        std::vector<pinocchio::Force> H(m.njoints);
        for (long k = 0; k < n; ++k) {
            if (gravity) m.gravity.linear(Eigen::Map<const Eigen::Vector3d>(gravity->data() + 3 * k));
            const Eigen::Map<const Eigen::VectorXd> q(Q.data() + k * m.nq, m.nq), v(V.data() + k * m.nv, m.nv);
            // O(n), not computeCoriolisMatrix's O(n²): with H_j the world-frame momentum of joint j's subtree,
            // p_j = S_jᵀ H_j and (Cᵀq̇)_j = Ṡ_jᵀ H_j, Ṡ_j = v_j × S_j (Ṁq̇ − Cq̇: the bodies' momentum rates cancel)
            algo::jacobians_time_variation(m, data, q, v);
            for (pinocchio::JointIndex i = 1; i < static_cast<pinocchio::JointIndex>(m.njoints); ++i)
                H[i] = data.oMi[i].act(m.inertias[i] * data.v[i]);
            for (pinocchio::JointIndex i = m.njoints - 1; i > 0; --i)
                if (m.parents[i] > 0) H[m.parents[i]] += H[i];
            const Eigen::VectorXd& g = algo::gravity(m, data, q);
            double* p = P.data() + k * m.nv;
            double* b = B.data() + k * m.nv;
            for (pinocchio::JointIndex i = 1; i < static_cast<pinocchio::JointIndex>(m.njoints); ++i) {
                const int i0 = m.idx_vs[i];
                for (int c = i0; c < i0 + m.nvs[i]; ++c) {
                    p[c] = data.J.col(c).dot(H[i].toVector());
                    b[c] = data.dJ.col(c).dot(H[i].toVector()) - g[c];
                }
            }
        }
    }

private:
    pinocchio::Model model_;
};

// y_k = a_k y_{k−1} + (1 − a_k) x_k, a_k = exp(−k_o Δt_k), from rest: the reference's loop, column by column.
void first_order(CArray1 dt, CArray2 x, double k_o, CArray2Out y) {
    const long n = static_cast<long>(x.shape(0)), c = static_cast<long>(x.shape(1));
    if (dt.shape(0) != static_cast<size_t>(n)) throw std::invalid_argument("dt: one step per sample");
    if (y.shape(0) != x.shape(0) || y.shape(1) != x.shape(1)) throw std::invalid_argument("y: the shape of x");
    nb::gil_scoped_release release;
    std::vector<double> prev(c, 0.0);
    for (long k = 0; k < n; ++k) {
        const double a = std::exp(-k_o * dt.data()[k]);
        for (long j = 0; j < c; ++j) {
            prev[j] = a * prev[j] + (1.0 - a) * x.data()[k * c + j];
            y.data()[k * c + j] = prev[j];
        }
    }
}

// The supply tracker's recursion on one input channel (dynid.identify.supply.SupplyTracker.apply), the same
// operations in the same order: residual = y − r·ŷ; where the row moves and |residual| ≤ gate, num, den and r update.
std::tuple<double, double, double> supply_track(CArray1 y, CArray1 predicted, CArray1 decay,
                                                nb::ndarray<const bool, nb::ndim<1>, nb::c_contig, nb::device::cpu> moving,
                                                double gate, double prior, double num, double den, double r,
                                                Array1 out, Array1 used) {
    const size_t n = y.shape(0);
    if (predicted.shape(0) != n || decay.shape(0) != n || moving.shape(0) != n || out.shape(0) != n ||
        used.shape(0) != n)
        throw std::invalid_argument("supply_track: every array holds one value per sample");
    nb::gil_scoped_release release;
    for (size_t k = 0; k < n; ++k) {
        const double yk = y.data()[k], pk = predicted.data()[k], lam = decay.data()[k];
        const double residual = yk - r * pk;
        out.data()[k] = residual;
        used.data()[k] = r;
        if (moving.data()[k] && std::abs(residual) <= gate) {
            num = lam * num + (1.0 - lam) * pk * yk;
            den = lam * den + (1.0 - lam) * pk * pk;
            r = (num + prior) / (den + prior);
        }
    }
    return {num, den, r};
}

}  // namespace

void register_observer(nb::module_& m) {
    nb::class_<MomentumTerms>(m, "MomentumTerms")
        .def(nb::init<const std::string&>(), nb::arg("model"),
             "model: a Pinocchio model serialised by Model.saveToString() (the split model, identified inertias)")
        .def_prop_ro("nq", &MomentumTerms::nq)
        .def_prop_ro("nv", &MomentumTerms::nv)
        .def("compute", &MomentumTerms::compute, nb::arg("q"), nb::arg("v"), nb::arg("gravity").none(), nb::arg("p"),
             nb::arg("beta"), "p = M q̇ and β = Cᵀq̇ − g of every sample into p and beta (N, nv)");
    m.def("first_order", &first_order, nb::arg("dt"), nb::arg("x"), nb::arg("k_o"), nb::arg("y"),
          "The observer's first-order low-pass over non-uniform steps dt (N,) of x (N, C) into y");
    m.def("supply_track", &supply_track, nb::arg("y"), nb::arg("predicted"), nb::arg("decay"), nb::arg("moving"),
          nb::arg("gate"), nb::arg("prior"), nb::arg("num"), nb::arg("den"), nb::arg("ratio"), nb::arg("out"),
          nb::arg("used"), "The supply tracker over one channel's samples; returns its state (num, den, ratio)");
}

}  // namespace dynid
