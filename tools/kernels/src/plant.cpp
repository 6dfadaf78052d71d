// The simulated plant over a whole run (dynid.simulation): the closed loop of boards, controller, motors and rigid
// bodies one sample after another (experiment.simulate's loop), its integration step (plant.RigidBodyPlant.step:
// semi-implicit Euler with implicit friction, an active set with an exact line search), and the F/T sensors'
// measurement afterwards (plant.RigidBodyPlant.sensor_wrenches), on Pinocchio's C++ API. The Python code stays the
// reference; the plan (gains, friction laws, hidden effects) comes from it as arrays (dynid.simulation.kernel).
#include "algorithms.hpp"
#include "bindings.hpp"
#include "pinocchio_model.hpp"

#include <nanobind/stl/array.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <optional>
#include <tuple>
#include <vector>

namespace dynid {

namespace {

using VectorXd = Eigen::VectorXd;
using MatrixXd = Eigen::MatrixXd;
using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

constexpr int kMaxActiveSetIterations = 12;  // plant.MAX_ACTIVE_SET_ITERATIONS
constexpr double kStickBand = 1e-4;          // actuation.STICK_BAND
constexpr double kEndStopStiffness = 200.0;  // actuation.END_STOP_STIFFNESS
constexpr double kEndStopDamping = 2.0;      // actuation.END_STOP_DAMPING

VectorXd vec(const nb::dict& d, const char* key) {
    const CArray1 a = nb::cast<CArray1>(d[key]);
    return Eigen::Map<const VectorXd>(a.data(), static_cast<long>(a.shape(0)));
}

MatrixXd mat(const nb::dict& d, const char* key) {
    const CArray2 a = nb::cast<CArray2>(d[key]);
    return Eigen::Map<const RowMatrix>(a.data(), static_cast<long>(a.shape(0)), static_cast<long>(a.shape(1)));
}

// The friction law of one step on the coordinates w = S q̇ (actuation.FrictionStep).
struct Law {
    VectorXd cp, cn, vp, vn, slope, upper, lower;
    void set(const VectorXd& cp_, const VectorXd& cn_, const VectorXd& vp_, const VectorXd& vn_) {
        cp = cp_, cn = cn_, vp = vp_, vn = vn_;
        slope = (0.5 * (cp + cn)).array() / kStickBand + vp.array() + vn.array();
        upper = cp.array() / (slope - vp).array();
        lower = (-cn).array() / (slope - vn).array();
    }
    double f(int i, double w) const {  // plant._friction
        return w > upper[i] ? cp[i] + vp[i] * w : (w < lower[i] ? -cn[i] + vn[i] * w : slope[i] * w);
    }
};

class Plant {
public:
    Plant(const std::string& model, std::optional<CArray2> armature, CArray2 S)
        : model_(load_model(model)), data_(model_), rnea_data_(model_),
          S_(Eigen::Map<const RowMatrix>(S.data(), S.shape(0), S.shape(1))), St_(S_.transpose()) {
        if (S_.cols() != model_.nv) throw std::invalid_argument("S: one column per velocity");
        if (armature) {
            armature_ = Eigen::Map<const RowMatrix>(armature->data(), armature->shape(0), armature->shape(1));
            if (armature_.rows() != model_.nv || armature_.cols() != model_.nv)
                throw std::invalid_argument("armature: (nv, nv)");
        }
        fext_.assign(model_.njoints, pinocchio::Force::Zero());
    }
    pinocchio::Model& model() { return model_; }
    int nv() const { return model_.nv; }
    int coordinates() const { return static_cast<int>(S_.rows()); }
    long unconverged = 0;

    // plant.RigidBodyPlant.step: v⁺ of M (v⁺ − v)/h + b(q, v) = τ_0 − Sᵀ f(S v⁺); `mode` (+1/−1/0) updated.
    void step(const VectorXd& q, const VectorXd& v, const VectorXd& tau0, const Law& law, double h, int fext_joint,
              const pinocchio::Force& fext, Eigen::Matrix<int8_t, Eigen::Dynamic, 1>& mode, VectorXd& x) {
        MatrixXd M = algo::crba(model_, data_, q);
        M.triangularView<Eigen::StrictlyLower>() = M.transpose().triangularView<Eigen::StrictlyLower>();
        if (armature_.size()) M += armature_;
        const VectorXd zero = VectorXd::Zero(model_.nv);
        VectorXd bias;
        if (fext_joint >= 0) {
            fext_[fext_joint] = fext;
            bias = algo::rnea(model_, rnea_data_, q, v, zero, fext_);
            fext_[fext_joint] = pinocchio::Force::Zero();
        } else {
            bias = algo::rnea(model_, rnea_data_, q, v, zero);
        }
        const VectorXd base = M * v + h * (tau0 - bias);
        x = v;
        VectorXd w = S_ * x;
        set_mode(w, law, mode);
        const int nc = coordinates();
        VectorXd slope(nc), offset(nc);
        for (int it = 0; it < kMaxActiveSetIterations; ++it) {
            for (int i = 0; i < nc; ++i) {
                const bool up = mode[i] > 0, down = mode[i] < 0;
                slope[i] = up ? law.vp[i] : (down ? law.vn[i] : law.slope[i]);
                offset[i] = (up ? law.cp[i] : 0.0) - (down ? law.cn[i] : 0.0);
            }
            const MatrixXd K = M + h * (St_ * slope.asDiagonal()) * S_;
            Eigen::LLT<MatrixXd> llt(K);
            if (llt.info() != Eigen::Success)
                throw std::runtime_error("the plant's mass matrix is not positive definite: check the inertias");
            const VectorXd x_newton = llt.solve(base - h * (St_ * offset));
            w = S_ * x_newton;
            bool same = true;
            for (int i = 0; i < nc; ++i) same &= mode_of(w[i], law, i) == mode[i];
            if (same) {
                x = x_newton;
                return;
            }
            const VectorXd d = x_newton - x;
            x += line_search(x, d, M, base, h, law) * d;
            w = S_ * x;
            set_mode(w, law, mode);
        }
        ++unconverged;
    }

private:
    static int8_t mode_of(double w, const Law& law, int i) {
        return static_cast<int8_t>((w > law.upper[i]) - (w < law.lower[i]));
    }
    void set_mode(const VectorXd& w, const Law& law, Eigen::Matrix<int8_t, Eigen::Dynamic, 1>& mode) const {
        for (int i = 0; i < coordinates(); ++i) mode[i] = mode_of(w[i], law, i);
    }
    // plant._line_search: the exact minimiser t ∈ (0, 1] of the step's convex objective along x + t d
    double line_search(const VectorXd& x, const VectorXd& d, const MatrixXd& M, const VectorXd& base, double h,
                       const Law& law) const {
        const VectorXd w0 = S_ * x, dw = S_ * d;
        std::vector<double> ts;
        for (int i = 0; i < coordinates(); ++i)
            for (double edge : {law.upper[i], law.lower[i]}) {
                const double t = (edge - w0[i]) / dw[i];
                if (t > 0.0 && t < 1.0) ts.push_back(t);
            }
        ts.push_back(1.0);
        std::sort(ts.begin(), ts.end());
        ts.erase(std::unique(ts.begin(), ts.end()), ts.end());
        const double a0 = d.dot(M * x - base), a1 = (d.transpose() * M).dot(d);
        auto slope_at = [&](double t) {
            double s = 0.0;
            for (int i = 0; i < coordinates(); ++i) s += law.f(i, w0[i] + t * dw[i]) * dw[i];
            return a0 + t * a1 + h * s;
        };
        double t_lo = 0.0, g_lo = 0.0;
        for (size_t k = 0; k < ts.size(); ++k) {
            const double g = slope_at(ts[k]);
            if (g >= 0.0) {
                if (k == 0) {
                    double s = 0.0;
                    for (int i = 0; i < coordinates(); ++i) s += law.f(i, w0[i]) * dw[i];
                    g_lo = a0 + h * s;
                }
                return g > g_lo ? t_lo + (ts[k] - t_lo) * (-g_lo) / (g - g_lo) : ts[k];
            }
            t_lo = ts[k];
            g_lo = g;
        }
        return 1.0;
    }

    pinocchio::Model model_;
    pinocchio::Data data_, rnea_data_;
    RowMatrix S_;
    MatrixXd St_, armature_;
    pinocchio::container::aligned_vector<pinocchio::Force> fext_;
};

// One run of experiment.simulate's loop: quantised encoders → impedance controller with CAD gravity → motor inputs
// (saturated, quantised) → actuators (supply, ripple, hidden effects, friction law) → plant step(s).
class ClosedLoop {
public:
    ClosedLoop(const std::string& plant, const std::string& cad, std::optional<CArray2> armature, const nb::dict& p)
        : plant_(plant, armature, nb::cast<CArray2>(p["S"])), cad_(load_model(cad)), cad_data_(cad_) {
        K_ = vec(p, "K"), D_ = vec(p, "D"), encoder_ = vec(p, "encoder"), lo_ = vec(p, "lo"), hi_ = vec(p, "hi");
        scale_ = vec(p, "scale"), rounded_ = vec(p, "rounded"), gain_ = vec(p, "gain"), deadzone_ = vec(p, "deadzone");
        ripple_phase_ = vec(p, "ripple_phase"), cogging_ = vec(p, "cogging"), cog_k_ = vec(p, "cogging_wavenumber");
        cog_phase_ = vec(p, "cogging_phase"), direct_ = vec(p, "direct"), spring_ = vec(p, "spring");
        rest_ = vec(p, "spring_rest"), drag_ = vec(p, "drag"), lower_ = vec(p, "lower"), upper_ = vec(p, "upper");
        stribeck_ = vec(p, "stribeck"), stribeck_v_ = vec(p, "stribeck_velocity"), load_ = vec(p, "load_friction");
        motor_coordinate_ = vec(p, "motor_coordinate");
        T_ = mat(p, "T"), to_inputs_ = mat(p, "to_inputs");
        base_.set(vec(p, "coulomb_pos"), vec(p, "coulomb_neg"), vec(p, "viscous_pos"), vec(p, "viscous_neg"));
        alpha_ = nb::cast<double>(p["alpha"]), dt_ = nb::cast<double>(p["dt"]), ripple_ = nb::cast<double>(p["ripple"]);
        ripple_wavenumber_ = nb::cast<double>(p["ripple_wavenumber"]);
        noise_ = nb::cast<bool>(p["noise"]), has_deadzone_ = nb::cast<bool>(p["has_deadzone"]);
        has_effects_ = nb::cast<bool>(p["has_effects"]), all_rounded_ = nb::cast<bool>(p["all_rounded"]);
        extra_law_ = stribeck_.any() || load_.any();
        const int nj = plant_.nv();
        if (K_.size() != nj || T_.cols() != nj || to_inputs_.cols() != nj || cad_.nv != nj)
            throw std::invalid_argument("closed loop: sizes differ from the plant's joints");
    }

    // The run: Q, V, A, U, TAU (commanded), UNSAT (unsaturated inputs), STUCK; returns (unconverged steps, the sample
    // at which the plant diverged or -1).
    std::tuple<long, long> run(CArray1 q0, CArray2 ref_q, CArray2 ref_dq, CArray2 supply, nb::ndarray<const int64_t,
                               nb::ndim<1>, nb::c_contig, nb::device::cpu> contact_joint, CArray2 contact_force,
                               std::optional<CArray2> gravity, int substeps, CArray2Out Q, CArray2Out V, CArray2Out A,
                               CArray2Out U, CArray2Out TAU, CArray2Out UNSAT,
                               nb::ndarray<bool, nb::ndim<2>, nb::c_contig, nb::device::cpu> STUCK) {
        const int nj = plant_.nv(), nm = static_cast<int>(T_.rows()), nc = plant_.coordinates();
        const long n = rows_of(ref_q, "ref_q", nj);
        shape2(ref_dq, n, nj, "ref_dq");
        shape2(supply, n, nm, "supply");
        shape2(contact_force, n, 6, "contact_force");
        if (contact_joint.shape(0) != static_cast<size_t>(n)) throw std::invalid_argument("contact_joint: one per sample");
        if (gravity) shape2(*gravity, n, 3, "gravity");
        for (auto* o : {&Q, &V, &A, &TAU})
            if (o->shape(0) != static_cast<size_t>(n) || o->shape(1) != static_cast<size_t>(nj))
                throw std::invalid_argument("outputs: (N, joints)");
        for (auto* o : {&U, &UNSAT})
            if (o->shape(0) != static_cast<size_t>(n) || o->shape(1) != static_cast<size_t>(nm))
                throw std::invalid_argument("outputs: (N, motors)");
        if (STUCK.shape(0) != static_cast<size_t>(n) || STUCK.shape(1) != static_cast<size_t>(nc))
            throw std::invalid_argument("stuck: (N, coordinates)");
        nb::gil_scoped_release release;
        const double h = dt_ / substeps;
        VectorXd q = Eigen::Map<const VectorXd>(q0.data(), nj), v = VectorXd::Zero(nj);
        VectorXd q_prev = q, vf = VectorXd::Zero(nj), x(nj);  // the controller's state (ImpedanceController.reset)
        Eigen::Matrix<int8_t, Eigen::Dynamic, 1> mode = Eigen::Matrix<int8_t, Eigen::Dynamic, 1>::Zero(nc);
        Law law = base_;
        long diverged = -1;
        for (long k = 0; k < n; ++k) {
            VectorXd qm = q;
            if (noise_) qm = ((q.array() / encoder_.array()).unaryExpr([](double y) { return std::nearbyint(y); }) *
                              encoder_.array()).matrix();
            // ImpedanceController.torque
            const VectorXd v_raw = (qm - q_prev) / dt_;
            vf = alpha_ * vf + (1.0 - alpha_) * v_raw;
            q_prev = qm;
            const Eigen::Map<const VectorXd> qd(ref_q.data() + k * nj, nj), vd(ref_dq.data() + k * nj, nj);
            const VectorXd tau_cmd = (K_.array() * (qd - qm).array() + D_.array() * (vd - vf).array()).matrix() +
                                     algo::gravity(cad_, cad_data_, qm);
            VectorXd u = to_inputs_ * tau_cmd;
            Eigen::Map<VectorXd>(UNSAT.data() + k * nm, nm) = u;
            u = u.cwiseMax(lo_).cwiseMin(hi_);  // sensors.InputQuantiser
            for (int i = 0; i < nm; ++i)
                if (all_rounded_ || rounded_[i] != 0.0) u[i] = std::nearbyint(u[i] * scale_[i]) / scale_[i];
            const int cj = static_cast<int>(contact_joint.data()[k]);
            const pinocchio::Force fc(Eigen::Map<const Vec6>(contact_force.data() + 6 * k));
            if (gravity) plant_.model().gravity.linear(Eigen::Map<const Eigen::Vector3d>(gravity->data() + 3 * k));
            const Eigen::Map<const VectorXd> s_k(supply.data() + k * nm, nm);
            for (int s = 0; s < substeps; ++s) {
                const VectorXd tau0 = drive(q, v, u, s_k, tau_cmd, law);
                plant_.step(q, v, tau0, law, h, cj, fc, mode, x);
                if (s == 0) {
                    Eigen::Map<VectorXd>(Q.data() + k * nj, nj) = q;
                    Eigen::Map<VectorXd>(V.data() + k * nj, nj) = x;
                    Eigen::Map<VectorXd>(A.data() + k * nj, nj) = (x - v) / h;
                    for (int i = 0; i < nc; ++i) STUCK.data()[k * nc + i] = mode[i] == 0;
                }
                v = x;
                q = q + h * v;
            }
            Eigen::Map<VectorXd>(U.data() + k * nm, nm) = u;
            Eigen::Map<VectorXd>(TAU.data() + k * nj, nj) = tau_cmd;
            if (!q.allFinite()) {
                diverged = k;
                break;
            }
        }
        return {plant_.unconverged, diverged};
    }

private:
    // Actuators.drive: τ_0, and the friction law of this step in `law`
    VectorXd drive(const VectorXd& q, const VectorXd& v, const VectorXd& u, const Eigen::Map<const VectorXd>& supply,
                   const VectorXd& tau_direct, Law& law) const {
        VectorXd duty = u;
        if (has_deadzone_)
            for (int i = 0; i < u.size(); ++i)
                duty[i] = (u[i] > 0 ? 1.0 : (u[i] < 0 ? -1.0 : 0.0)) * std::max(std::abs(u[i]) - deadzone_[i], 0.0);
        VectorXd drive = (gain_.array() * supply.array() * duty.array()).matrix();
        const VectorXd qm = T_ * q;
        if (ripple_ != 0.0)
            drive = (drive.array() * (1.0 + ripple_ * (ripple_wavenumber_ * qm.array() + ripple_phase_.array()).sin()))
                        .matrix();
        VectorXd motor = drive;
        if (has_effects_) motor = drive + (cogging_.array() * (cog_k_.array() * qm.array() + cog_phase_.array()).sin()).matrix();
        VectorXd tau = T_.transpose() * motor + (direct_.array() * tau_direct.array()).matrix();
        if (has_effects_)
            tau -= (spring_.array() * (q - rest_).array() + drag_.array() * v.array() * v.array().abs()).matrix();
        for (int i = 0; i < q.size(); ++i) {
            const bool below = q[i] < lower_[i], above = q[i] > upper_[i];
            if (below || above) {
                const double past = (below ? q[i] - lower_[i] : 0.0) + (above ? q[i] - upper_[i] : 0.0);
                tau[i] -= kEndStopStiffness * past + kEndStopDamping * v[i];
            }
        }
        if (!extra_law_) {
            law = base_;
            return tau;
        }
        VectorXd extra = VectorXd::Zero(base_.cp.size());
        for (int i = 0; i < q.size(); ++i)
            extra[i] = stribeck_[i] * std::exp(-(v[i] / stribeck_v_[i]) * (v[i] / stribeck_v_[i]));
        for (int m = 0; m < load_.size(); ++m)
            extra[static_cast<int>(motor_coordinate_[m])] += load_[m] * std::abs(drive[m]);
        law.set(base_.cp + extra, base_.cn + extra, base_.vp, base_.vn);
        return tau;
    }

    Plant plant_;
    pinocchio::Model cad_;
    pinocchio::Data cad_data_;
    VectorXd K_, D_, encoder_, lo_, hi_, scale_, rounded_, gain_, deadzone_, ripple_phase_, cogging_, cog_k_,
        cog_phase_, direct_, spring_, rest_, drag_, lower_, upper_, stribeck_, stribeck_v_, load_, motor_coordinate_;
    MatrixXd T_, to_inputs_;
    Law base_;
    double alpha_ = 0, dt_ = 0, ripple_ = 0, ripple_wavenumber_ = 0;
    bool noise_ = false, has_deadzone_ = false, has_effects_ = false, all_rounded_ = false, extra_law_ = false;
};

// plant.RigidBodyPlant.sensor_wrenches over a trajectory.
struct Site { int joint; pinocchio::SE3 placement; int sensor; };
struct Mount { int joint; pinocchio::SE3 placement; pinocchio::Inertia distal; std::vector<int> children; };

void sensor_wrenches(const std::string& serialized, const std::vector<std::tuple<int, std::array<double, 12>, int>>& sites,
                     const std::vector<std::tuple<int, std::array<double, 12>, std::array<double, 10>, std::vector<int>>>& mounts,
                     nb::ndarray<const bool, nb::ndim<2>, nb::c_contig, nb::device::cpu> distal, CArray2 Q, CArray2 V,
                     CArray2 A, nb::ndarray<const int64_t, nb::ndim<1>, nb::c_contig, nb::device::cpu> site_index,
                     CArray2 wrench, std::optional<CArray2> gravity, Array3 measured, Array3 from_contact,
                     CArray2Out tau_contact) {
    pinocchio::Model m = load_model(serialized);
    auto se3 = [](const std::array<double, 12>& a) {  // rotation row-major, then translation
        return pinocchio::SE3(Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(a.data()),
                              Eigen::Vector3d(a[9], a[10], a[11]));
    };
    std::vector<Site> S;
    for (const auto& [j, p, s] : sites) S.push_back({j, se3(p), s});
    std::vector<Mount> M;
    for (const auto& [j, p, phi, children] : mounts)
        M.push_back({j, se3(p), pinocchio::Inertia::FromDynamicParameters(Eigen::Map<const Eigen::Matrix<double, 10, 1>>(phi.data())),
                     children});
    const long n = rows_of(Q, "q", m.nv);
    shape2(V, n, m.nv, "v");
    shape2(A, n, m.nv, "a");
    shape2(wrench, n, 6, "wrench");
    if (gravity) shape2(*gravity, n, 3, "gravity");
    const size_t ns = M.size();
    if (distal.shape(0) != S.size() || distal.shape(1) != ns) throw std::invalid_argument("distal: (sites, sensors)");
    for (auto* o : {&measured, &from_contact})
        if (o->shape(0) != static_cast<size_t>(n) || o->shape(1) != ns || o->shape(2) != 6)
            throw std::invalid_argument("measured, from_contact: (N, sensors, 6)");
    for (long k = 0; k < n; ++k) {
        const long c = site_index.data()[k];
        if (c >= static_cast<long>(S.size())) throw std::invalid_argument("site_index out of range");
    }
    nb::gil_scoped_release release;
    pinocchio::Data data(m);
    pinocchio::container::aligned_vector<pinocchio::Force> fext(m.njoints, pinocchio::Force::Zero());
    std::vector<pinocchio::Inertia> sub(ns);
    for (size_t i = 0; i < ns; ++i) sub[i] = M[i].placement.act(M[i].distal);
    auto put = [](Array3& a, long k, size_t i, const Vec6& x) {
        for (int j = 0; j < 6; ++j) a.data()[k * a.stride(0) + i * a.stride(1) + j * a.stride(2)] = x[j];
    };
    for (long k = 0; k < n; ++k) {
        if (gravity) m.gravity.linear(Eigen::Map<const Eigen::Vector3d>(gravity->data() + 3 * k));
        const Eigen::Map<const VectorXd> q(Q.data() + k * m.nv, m.nv), v(V.data() + k * m.nv, m.nv),
            a(A.data() + k * m.nv, m.nv);
        const long c = site_index.data()[k];
        Eigen::Map<VectorXd> tc(tau_contact.data() + k * m.nv, m.nv);
        pinocchio::Force f_link = pinocchio::Force::Zero();
        if (c >= 0) {
            f_link = pinocchio::Force(Eigen::Map<const Vec6>(wrench.data() + 6 * k));
            const VectorXd tau_free = algo::rnea(m, data, q, v, a);
            fext[S[c].joint] = S[c].placement.act(f_link);
            tc = tau_free - algo::rnea(m, data, q, v, a, fext);
            fext[S[c].joint] = pinocchio::Force::Zero();
        } else {
            algo::rnea(m, data, q, v, a);
            tc.setZero();
        }
        for (size_t i = 0; i < ns; ++i) {
            const Mount& s = M[i];
            const pinocchio::Motion& va = data.v[s.joint];
            const pinocchio::Motion& aa = data.a_gf[s.joint];
            pinocchio::Force f = sub[i] * aa + va.cross(sub[i] * va);
            for (int child : s.children) f += data.liMi[child].act(data.f[child]);
            if (c >= 0 && S[c].sensor == static_cast<int>(i)) f -= S[c].placement.act(f_link);
            put(measured, k, i, -s.placement.actInv(f).toVector());
            Vec6 contact = Vec6::Zero();
            if (c >= 0 && distal.data()[c * ns + i]) {
                pinocchio::SE3 anchor_M_link = S[c].placement;
                for (int j = S[c].joint; j != s.joint; j = m.parents[j]) anchor_M_link = data.liMi[j] * anchor_M_link;
                contact = s.placement.actInv(anchor_M_link).act(f_link).toVector();
            }
            put(from_contact, k, i, contact);
        }
    }
}

}  // namespace

void register_plant(nb::module_& m) {
    nb::class_<ClosedLoop>(m, "ClosedLoop")
        .def(nb::init<const std::string&, const std::string&, std::optional<CArray2>, const nb::dict&>(),
             nb::arg("plant"), nb::arg("cad"), nb::arg("armature").none(), nb::arg("plan"),
             "plant, cad: serialised Pinocchio models (the true plant, the controller's CAD plant); plan: the "
             "controller's, boards' and actuators' arrays (dynid.simulation.kernel.plan)")
        .def("run", &ClosedLoop::run, nb::arg("q0"), nb::arg("ref_q"), nb::arg("ref_dq"), nb::arg("supply"),
             nb::arg("contact_joint"), nb::arg("contact_force"), nb::arg("gravity").none(), nb::arg("substeps"),
             nb::arg("Q"), nb::arg("V"), nb::arg("A"), nb::arg("U"), nb::arg("TAU"), nb::arg("UNSAT"), nb::arg("STUCK"),
             "The closed loop over a run; returns (unconverged steps, the sample where the plant diverged or -1)");
    m.def("sensor_wrenches", &sensor_wrenches, nb::arg("model"), nb::arg("sites"), nb::arg("mounts"),
          nb::arg("distal"), nb::arg("q"), nb::arg("v"), nb::arg("a"), nb::arg("site_index"), nb::arg("wrench"),
          nb::arg("gravity").none(), nb::arg("measured"), nb::arg("from_contact"), nb::arg("tau_contact"),
          "The F/T sensors' wrenches (and the contact's share) and the contact's joint torques over a trajectory");
}

}  // namespace dynid
