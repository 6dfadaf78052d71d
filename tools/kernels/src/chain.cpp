#include "chain.hpp"

#include <stdexcept>

namespace dynid {

namespace {

Mat3 skew(const Vec3& v) {
    Mat3 S;
    S << 0.0, -v[2], v[1], v[2], 0.0, -v[0], -v[1], v[0], 0.0;
    return S;
}

// Rotation about a unit axis by angle q (Rodrigues; Pinocchio's revolute joints, aligned or not).
Mat3 rotation(const Vec3& axis, double q) {
    const double c = std::cos(q), s = std::sin(q);
    const Mat3 K = skew(axis);
    return Mat3::Identity() + s * K + (1.0 - c) * (K * K);
}

}  // namespace

void body_regressor(const Vec3& v, const Vec3& w, const Vec3& a, const Vec3& alpha, BodyRegressor& Y) {
    const Vec3 acc = a + w.cross(v);
    Y.block<3, 1>(0, 0) = acc;
    Y.block<3, 3>(0, 1) = w * w.transpose() - w.squaredNorm() * Mat3::Identity() + skew(alpha);
    Y.block<3, 6>(0, 4).setZero();
    Y.block<3, 1>(3, 0).setZero();
    Y.block<3, 3>(3, 1) = skew(-acc);
    // cross(w, bigL(w)) + bigL(alpha), bigL(w) * [Ixx Ixy Iyy Ixz Iyz Izz] = I w
    const double x = w[0], y = w[1], z = w[2];
    Y.block<3, 6>(3, 4) << alpha[0], -z * x + alpha[1], -z * y, y * x + alpha[2], y * y - z * z, y * z,
        z * x, z * y + alpha[0], alpha[1], z * z - x * x, -y * x + alpha[2], -z * x,
        -y * x, x * x - y * y, y * x, -z * y + alpha[0], z * x + alpha[1], alpha[2];
}

Chain::Chain(std::vector<Joint> joints, const Vec3& gravity) : joints_(std::move(joints)), gravity_(gravity) {
    const int n = static_cast<int>(joints_.size());
    ancestors_.resize(n);
    for (int i = 0; i < n; ++i) {
        const Joint& J = joints_[i];
        if (J.parent >= i || J.parent < -1) throw std::invalid_argument("chain: joints must come parents first");
        if (J.kind == Held ? J.nv != 6 : J.nv != 1) throw std::invalid_argument("chain: a joint's nv does not fit its kind");
        if (J.kind != Held && J.q_col < 0) throw std::invalid_argument("chain: a moving joint needs its column in q");
        for (int j = i; j >= 0; j = joints_[j].parent) ancestors_[i].push_back(j);
        nv_ = std::max(nv_, J.v_row + J.nv);
        if (J.kind != Held) n_q_ = std::max(n_q_, J.q_col + 1);
    }
}

void Chain::kinematics(const double* q, const double* dq, const double* ddq, const double* gravity,
                       ChainState& s) const {
    const Vec3 g = gravity ? Vec3(gravity[0], gravity[1], gravity[2]) : gravity_;
    const Vec3 zero = Vec3::Zero();
    for (size_t i = 0; i < joints_.size(); ++i) {
        const Joint& J = joints_[i];
        Mat3& R = s.R[i];
        Vec3& p = s.p[i];
        double qi = 0.0, dqi = 0.0, ddqi = 0.0;
        if (J.kind != Held) {
            qi = q[J.q_col];
            dqi = dq[J.q_col];
            ddqi = ddq[J.q_col];
        }
        if (J.kind == Revolute) {
            R.noalias() = J.R * rotation(J.axis, qi);
            p = J.p;
        } else if (J.kind == Prismatic) {
            R = J.R;
            p = J.p + J.R * (J.axis * qi);
        } else {
            R = J.R;
            p = J.p;
        }
        const bool root = J.parent < 0;
        const Vec3& vl_p = root ? zero : s.v_lin[J.parent];
        const Vec3& w_p = root ? zero : s.v_ang[J.parent];
        const Vec3 al_p = root ? Vec3(-g) : s.a_lin[J.parent];
        const Vec3& alpha_p = root ? zero : s.a_ang[J.parent];
        // the parent's motion in this joint's frame (SE3::actInv), then the joint's own
        Vec3 w = R.transpose() * w_p;
        Vec3 vl = R.transpose() * (vl_p - p.cross(w_p));
        Vec3 alpha = R.transpose() * alpha_p;
        Vec3 al = R.transpose() * (al_p - p.cross(alpha_p));
        if (J.kind == Revolute) {
            const Vec3 vj = J.axis * dqi;
            w += vj;
            al += vl.cross(vj);
            alpha += J.axis * ddqi + w.cross(vj);
        } else if (J.kind == Prismatic) {
            const Vec3 vj = J.axis * dqi;
            vl += vj;
            al += J.axis * ddqi + w.cross(vj);
        }
        s.v_lin[i] = vl;
        s.v_ang[i] = w;
        s.a_lin[i] = al;
        s.a_ang[i] = alpha;
    }
}

namespace {

// Σ_r s[r] · Y(v, a)[r, :] for a motion axis s = (lin, ang) in the body's frame: one row of the joint-torque
// regressor, written out over body_regressor's structure (its 21 structural zeros skipped).
inline void axis_row(const Vec3& sl, const Vec3& sa, const Vec3& acc, const Mat3& B, const Vec3& w,
                     const Vec3& alpha, double* out) {
    out[0] = sl.dot(acc);
    // [sl]ᵀ B + [sa]ᵀ skew(−acc) = Bᵀ sl + acc × sa
    const Vec3 t = B.transpose() * sl + acc.cross(sa);
    out[1] = t[0];
    out[2] = t[1];
    out[3] = t[2];
    const double x = w[0], y = w[1], z = w[2];
    const double a = sa[0], b = sa[1], c = sa[2];
    out[4] = a * alpha[0] + b * z * x - c * y * x;
    out[5] = a * (-z * x + alpha[1]) + b * (z * y + alpha[0]) + c * (x * x - y * y);
    out[6] = -a * z * y + b * alpha[1] + c * y * x;
    out[7] = a * (y * x + alpha[2]) + b * (z * z - x * x) + c * (-z * y + alpha[0]);
    out[8] = a * (y * y - z * z) + b * (-y * x + alpha[2]) + c * (z * x + alpha[1]);
    out[9] = a * y * z - b * z * x + c * alpha[2];
}

}  // namespace

void Chain::regressor(const double* q, const double* dq, const double* ddq, const double* gravity, ChainState& s,
                      double* Y, long ld) const {
    kinematics(q, dq, ddq, gravity, s);
    const int nb = n_bodies();
    for (int r = 0; r < nv_; ++r) std::fill(Y + r * ld, Y + r * ld + 10 * nb, 0.0);
    // world poses of the joint frames, and the joints' axes in the world frame
    std::vector<Mat3>& oR = s.oR;
    std::vector<Vec3>& op = s.op;
    for (int i = 0; i < nb; ++i) {
        const Joint& J = joints_[i];
        if (J.parent < 0) {
            oR[i] = s.R[i];
            op[i] = s.p[i];
        } else {
            oR[i].noalias() = oR[J.parent] * s.R[i];
            op[i] = oR[J.parent] * s.p[i] + op[J.parent];
        }
        if (J.kind == Revolute) {
            s.axis_ang[i] = oR[i] * J.axis;
            s.axis_lin[i] = op[i].cross(s.axis_ang[i]);
        } else if (J.kind == Prismatic) {
            s.axis_lin[i] = oR[i] * J.axis;
            s.axis_ang[i].setZero();
        }
    }
    for (int i = 0; i < nb; ++i) {
        const Vec3 &v = s.v_lin[i], &w = s.v_ang[i], &alpha = s.a_ang[i];
        const Vec3 acc = s.a_lin[i] + w.cross(v);
        const Mat3 B = w * w.transpose() - w.squaredNorm() * Mat3::Identity() + skew(alpha);
        const Mat3 Rt = oR[i].transpose();
        for (int j : ancestors_[i]) {
            const Joint& J = joints_[j];
            double* out = Y + J.v_row * ld + 10 * i;
            // j == i: the joint's own frame, taken as it is (not through the world frame and back), so that what
            // is structurally zero there is exactly zero, as in Pinocchio's regressor (a column that only rounding
            // fills would become a unit-norm predictor once PLS scales its columns)
            if (J.kind == Held) {  // six rows: the body's wrench regressor in the sensor frame (j_M_i acting)
                const Mat3 R = j == i ? Mat3::Identity() : Mat3(oR[j].transpose() * oR[i]);
                const Vec3 p = j == i ? Vec3::Zero() : Vec3(oR[j].transpose() * (op[i] - op[j]));
                BodyRegressor Yb;
                body_regressor(v, w, s.a_lin[i], alpha, Yb);
                for (int c = 0; c < 10; ++c) {
                    const Vec3 f = R * Yb.block<3, 1>(0, c);
                    const Vec3 t = R * Yb.block<3, 1>(3, c) + p.cross(f);
                    for (int k = 0; k < 3; ++k) {
                        out[k * ld + c] = f[k];
                        out[(3 + k) * ld + c] = t[k];
                    }
                }
                continue;
            }
            // the joint's axis in body i's frame (SE3::actInv of the world axis), against the body's regressor
            if (j == i) {
                const Vec3 zero = Vec3::Zero();
                axis_row(J.kind == Revolute ? zero : J.axis, J.kind == Revolute ? J.axis : zero, acc, B, w, alpha, out);
                continue;
            }
            const Vec3 sa = Rt * s.axis_ang[j];
            const Vec3 sl = Rt * (s.axis_lin[j] - op[i].cross(s.axis_ang[j]));
            axis_row(sl, sa, acc, B, w, alpha, out);
        }
    }
}

}  // namespace dynid
