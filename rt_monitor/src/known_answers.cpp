// The coefficient file's known answers (format version 7, dynid.export.known_answers): at load, the core runs over
// the file's stored samples and must give, sample by sample, what dynid computed offline from the model file. The
// CRC catches a corrupt file; this catches one that is well formed but wrong — an edited value that is plausible on
// its own (a joint without friction, a gate lost, supply tracking off), an exporter or a loader that gets a field
// wrong — which nothing else at the monitor can tell from the right one (docs/fuzzing.md, "The mutation sweep").
// Start-up only: the test core is allocated here, once.
#include "coefficient_checks.hpp"
#include "rt_monitor/core.hpp"

#include <cmath>
#include <memory>
#include <sstream>

namespace dynid::rt {
namespace {

// As dynid.export.known_answers: the two sides agree to about 1e-12; an edit that matters moves far more.
constexpr double kRelTol = 1e-6, kAbsTol = 1e-9;

bool same(double a, double b) {
    return std::abs(a - b) <= kRelTol * std::max(std::abs(a), std::abs(b)) + kAbsTol;
}

// The columns the core gives at this sample, in the file's order (see coefficients_t.lcm).
int columns_of(const Core& core, const Coefficients& c, double* x) {
    const Output& o = core.output();
    int n = 0;
    x[n++] = o.p.t2 / o.t2_alpha;
    const bool combined = core.residual() == Residual::kCombined;
    if (combined) {
        x[n++] = o.observer_ratio;
        x[n++] = o.acceleration_ratio;
    }
    const auto& side = core.residual() == Residual::kAcceleration ? c.ft_threshold : c.observer_ft_threshold;
    for (int k = 0; k < c.n_sensors; ++k) x[n++] = o.p.t2_sensor[k] / side[k];
    if (combined)
        for (int k = 0; k < c.n_sensors; ++k) x[n++] = core.acceleration_output().p.t2_sensor[k] / c.ft_threshold[k];
    return n;
}

std::string column_name(int i, const Coefficients& c, bool combined) {
    if (i == 0) return combined ? "s" : "T²/T²_α";
    if (combined && i == 1) return "the observer's T²/T²_α";
    if (combined && i == 2) return "the acceleration residuals' T²/T²_α";
    const int k = i - (combined ? 3 : 1);
    const bool acc = combined && k >= c.n_sensors;
    return std::string(acc ? "the acceleration residuals' " : "") + "share of " +
           shown_name(c.sensor_names[k % std::max(c.n_sensors, 1)]) + " over its side threshold";
}

}  // namespace

LoadResult check_known_answers(const dynid::coefficients_t& f, const Coefficients& c) {
    auto refuse = [](const std::string& m) { return fail(LoadError::kKnownAnswers, m); };
    const bool combined = c.residual == Residual::kCombined;
    const int nv = c.measured_velocity ? c.n_joints : 0;  // the robot's q̇, where the observer takes it
    const int width = c.n_joints + nv + c.n_outputs, columns = (combined ? 3 + 2 * c.n_sensors : 1 + c.n_sensors);
    if (f.known_width != width || f.known_columns != columns)
        return fail(LoadError::kDimension, "known answers of " + str(f.known_width) + " channels and " +
                                               str(f.known_columns) + " columns; the file's robot and detector need " +
                                               str(width) + " and " + str(columns));
    if (f.n_known == 0) {
        if (f.estimator == "cad") return LoadResult{};  // a CAD export has no data to take them on
        return refuse("a fitted model's file without known answers: export it again with this dynid");
    }
    auto core = std::make_unique<Core>(c);
    int compared = 0;
    double got[3 + 2 * kMaxSensors];
    for (int k = 0; k < f.n_known; ++k) {
        const auto& in = f.known_input[k];
        if (!finite_all(in)) return fail(LoadError::kNotFinite, "non-finite value in the known answers' samples");
        const Output& o = core->step(in.data(), nv ? in.data() + c.n_joints : nullptr, in.data() + c.n_joints + nv);
        const auto& want = f.known_answer[k];
        const bool expected = std::isfinite(want[0]);
        if (o.ready != expected) {
            std::ostringstream m;
            m << "known answers: the core " << (o.ready ? "evaluates" : "does not evaluate") << " sample " << k
              << ", the file says it " << (expected ? "does" : "does not");
            return refuse(m.str());
        }
        if (!o.ready) continue;
        columns_of(*core, c, got);
        for (int i = 0; i < columns; ++i) {
            if (same(got[i], want[i])) continue;  // NaN in either is a difference
            std::ostringstream m;
            m.precision(9);
            m << "the core does not reproduce the file's known answers: at sample " << k << ", "
              << column_name(i, c, combined) << " is " << got[i] << ", the file says " << want[i]
              << " (an edited file, or an exporter and a monitor that disagree; export it again)";
            return refuse(m.str());
        }
        ++compared;
    }
    if (compared == 0) return refuse("known answers: the core evaluates none of the file's samples");
    return LoadResult{};
}

}  // namespace dynid::rt
