// What the core's and the detector's tests share: the default arm's CAD coefficient file (tests/data/icub_cad.dcoef,
// RT_TEST_COEF), joint vectors of the monitor's capacity, and a core driven by an exact motion.
#pragma once

#include "rt_monitor/coefficients.hpp"
#include "rt_monitor/core.hpp"

#include <gtest/gtest.h>

#include <initializer_list>
#include <memory>

namespace dynid::rt::testing {

inline std::unique_ptr<Coefficients> load_fixture() {
    auto c = std::make_unique<Coefficients>();
    const LoadResult r = load_coefficients(RT_TEST_COEF, "icub_right_arm", *c);
    EXPECT_TRUE(bool(r)) << r.message;
    return c;
}

// A joint vector of the monitor's capacity: the given leading values, zeros beyond. (A comma initializer with fewer
// values than kMaxJoints leaves the rest uninitialised; Eigen asserts on it where NDEBUG is off: build-asan.)
inline VecJ joint_vector(std::initializer_list<double> values) {
    VecJ x = VecJ::Zero();
    int i = 0;
    for (double value : values) x[i++] = value;
    return x;
}

// A smooth motion (q linear in time: the filter reproduces it exactly) with its exact model outputs, plus a
// disturbance on chosen channels.
struct Scenario {
    std::unique_ptr<Coefficients> c = load_fixture();
    std::unique_ptr<Core> core = std::make_unique<Core>(*c);
    VecJ q0 = joint_vector({0.1, 0.4, 0.2, 0.8, 0.0, 0.1, -0.1});
    VecJ v = joint_vector({0.2, -0.15, 0.25, 0.3, -0.2, 0.1, 0.15});
    const Output& step(int k, const VecO& disturbance) {
        VecJ q = q0 + v * (1e-3 * k);
        Prediction p;
        core->predict(q, v, VecJ::Zero(), VecO::Zero(), p);
        VecO y = p.y_hat + disturbance;
        return core->step(q.data(), y.data());
    }
};

}  // namespace dynid::rt::testing
