#include "algorithms.hpp"

#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/rnea.hpp>

namespace dynid::algo {

const Eigen::VectorXd& rnea(const pinocchio::Model& m, pinocchio::Data& d, const Vector& q, const Vector& v,
                            const Vector& a) {
    return pinocchio::rnea(m, d, q, v, a);
}

const Eigen::VectorXd& rnea(const pinocchio::Model& m, pinocchio::Data& d, const Vector& q, const Vector& v,
                            const Vector& a, const Forces& fext) {
    return pinocchio::rnea(m, d, q, v, a, fext);
}

const Eigen::MatrixXd& crba(const pinocchio::Model& m, pinocchio::Data& d, const Vector& q) {
    return pinocchio::crba(m, d, q);
}

const Eigen::VectorXd& gravity(const pinocchio::Model& m, pinocchio::Data& d, const Vector& q) {
    return pinocchio::computeGeneralizedGravity(m, d, q);
}

void jacobians_time_variation(const pinocchio::Model& m, pinocchio::Data& d, const Vector& q, const Vector& v) {
    pinocchio::computeJointJacobiansTimeVariation(m, d, q, v);
}

}  // namespace dynid::algo
