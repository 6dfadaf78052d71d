// Coefficient-file loader: magic, version, length, CRC-32, LCM decode, capacity, dimensions, finite values,
// robot. Every check names what failed; nothing of a refused file is used.
#include "rt_monitor/coefficients.hpp"

#include "coefficient_checks.hpp"
#include "dynid/coefficients_t.hpp"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iterator>
#include <sstream>
#include <vector>

namespace dynid::rt {
namespace {

constexpr size_t kHeader = 16;  // magic (8) + version (4) + payload length (4)
constexpr size_t kMaxFileBytes = size_t(1) << 24;  // 16 MB: a full-capacity file with its known answers is ~1.2 MB

uint32_t read_le32(const uint8_t* p) {
    return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

}  // namespace

std::string escape_control(const std::string& s) {
    std::string out;
    for (const char ch : s) {
        const unsigned char b = static_cast<unsigned char>(ch);
        if (b < 0x20 || b == 0x7F) {
            static const char* hex = "0123456789ABCDEF";
            out += "\\x";
            out += hex[b >> 4];
            out += hex[b & 15];
        } else {
            out += ch;
        }
    }
    return out;
}

std::string shown_name(const std::string& s) {
    return s.size() > 80 ? escape_control(s.substr(0, 80)) + "…" : escape_control(s);
}

uint32_t crc32(const uint8_t* data, size_t size) {
    // CRC-32/IEEE 802.3 (zlib's), reflected, table-driven; the table is built once.
    static const auto table = [] {
        std::array<uint32_t, 256> t{};
        for (uint32_t i = 0; i < 256; ++i) {
            uint32_t c = i;
            for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
            t[i] = c;
        }
        return t;
    }();
    uint32_t c = 0xFFFFFFFFu;
    for (size_t i = 0; i < size; ++i) c = table[(c ^ data[i]) & 0xFF] ^ (c >> 8);
    return c ^ 0xFFFFFFFFu;
}

LoadResult load_coefficients(const std::string& path, const std::string& expected_robot, Coefficients& out) {
    // stdio, not an ifstream: libstdc++'s filebuf throws std::ios_failure from underflow on a read error, and
    // `rt_monitor --model DIR` (EISDIR) ended in std::terminate, SIGABRT (issue 22's sweep).
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) return fail(LoadError::kIo, path + ": cannot open the coefficient file: " + std::strerror(errno));
    std::vector<uint8_t> bytes;
    uint8_t block[65536];
    size_t n = 0;
    while ((n = std::fread(block, 1, sizeof block, f)) > 0 && bytes.size() <= kMaxFileBytes)
        bytes.insert(bytes.end(), block, block + n);
    const int read_errno = std::ferror(f) ? errno : 0;
    std::fclose(f);
    if (read_errno) return fail(LoadError::kIo, path + ": cannot read the coefficient file: " + std::strerror(read_errno));
    if (bytes.size() > kMaxFileBytes)  // /dev/zero, or a wrong file: not read to the end
        return fail(LoadError::kTruncated, path + ": larger than " + std::to_string(kMaxFileBytes) +
                                                " bytes, far more than a coefficient file holds");
    LoadResult r = load_coefficients_from_bytes(bytes.data(), bytes.size(), expected_robot, out);
    if (!r) r.message = path + ": " + r.message;
    return r;
}

LoadResult load_coefficients_from_bytes(const uint8_t* data, size_t size, const std::string& expected_robot,
                                        Coefficients& out) {
    if (size < kHeader + 4)
        return fail(LoadError::kTruncated, "truncated: " + std::to_string(size) + " bytes, shorter than the header");
    if (std::memcmp(data, kMagic, sizeof kMagic) != 0)
        return fail(LoadError::kMagic, "not a dynid coefficient file (bad magic)");
    const uint32_t version = read_le32(data + 8);
    if (version != uint32_t(kFileVersion))  // older: the model exports again; newer: this monitor is the old one
        return fail(LoadError::kVersion, "format version " + std::to_string(version) + ", this monitor reads " +
                                             std::to_string(kFileVersion) +
                                             (version < uint32_t(kFileVersion)
                                                  ? ": export the model again (dynid export)"
                                              // versions come one a format change: far beyond, a damaged file
                                              : version > uint32_t(kFileVersion) + 100
                                                  ? ": no dynid wrote that, the file is damaged (export it again)"
                                                  : ": a newer dynid wrote it: build this monitor from that dynid, or "
                                                    "export with this one"));
    const uint64_t length = read_le32(data + 12);
    if (size != kHeader + length + 4)
        return fail(LoadError::kTruncated, "truncated or padded: " + std::to_string(size) + " bytes, the header says " +
                                               std::to_string(kHeader + length + 4));
    if (crc32(data, kHeader + length) != read_le32(data + kHeader + length))
        return fail(LoadError::kCrc, "CRC mismatch (the file is corrupt)");

    // Counts and lengths first, without allocating (Shape): the decoder then allocates within the capacity only.
    if (LoadResult shape = check_shape(data + kHeader, size_t(length)); !shape) return shape;
    dynid::coefficients_t c;
    int used = -1;
    try {  // start-up only: the LCM decoder allocates (within the capacity, after check_shape)
        used = c.decode(data + kHeader, 0, int(length));
    } catch (...) {
        used = -1;
    }
    if (used != int(length)) return fail(LoadError::kDecode, "payload is not a dynid.coefficients_t (fingerprint or size)");

    auto cap = [](const char* what, int n, int max) {
        return fail(LoadError::kCapacity, std::string("too many ") + what + ": " + str(n) + " (this build's capacity is " +
                                              str(max) + ")");
    };
    if (c.n_joints > kMaxJoints) return cap("joints", c.n_joints, kMaxJoints);
    if (c.n_bodies > kMaxBodies) return cap("bodies", c.n_bodies, kMaxBodies);
    if (c.n_motors > kMaxMotors) return cap("motors", c.n_motors, kMaxMotors);
    if (c.n_outputs > kMaxOutputs) return cap("outputs", c.n_outputs, kMaxOutputs);
    if (c.window > kMaxWindow) return cap("filter samples", c.window, kMaxWindow);
    if (c.velocity_window > kMaxWindow) return cap("velocity filter samples", c.velocity_window, kMaxWindow);
    if (c.n_effects > kMaxEffects) return cap("effects", c.n_effects, kMaxEffects);
    auto dim = [](const std::string& m) { return fail(LoadError::kDimension, m); };
    if (c.n_sensors > kMaxSensors) return cap("F/T sensors", c.n_sensors, kMaxSensors);
    if (c.n_joints < 1 || c.n_bodies < c.n_joints || c.n_sensors < 0 || c.n_outputs < 1 || c.n_outputs < 6 * c.n_sensors ||
        c.n_motors < 0)
        return dim("dimensions out of range (joints " + str(c.n_joints) + ", bodies " + str(c.n_bodies) + ", F/T sensors " +
                   str(c.n_sensors) + ", outputs " + str(c.n_outputs) + ")");
    if (c.window < 3 || c.order < 2 || c.order >= c.window || c.lag < 0 || c.lag >= c.window)
        return dim("derivative filter settings out of range (window " + str(c.window) + ", order " + str(c.order) +
                   ", lag " + str(c.lag) + ")");
    for (int k = 0; k < c.n_sensors; ++k) {
        const int b = c.sensor_body[k];
        if (b < 0 || b >= c.n_bodies || c.joint_type[b] != 0)
            return dim("F/T sensor " + shown_name(c.sensor_names[k]) + ": its body must be a fixed split of the chain");
        for (int m = 0; m < k; ++m)
            if (c.sensor_body[m] == b) return dim("two F/T sensors on one body");
    }
    if (c.debounce_on < 1 || c.debounce_off < 1) return dim("debounce counts must be at least 1");
    if (c.n_effects < 0) return dim("negative effect count");
    for (int k = 0; k < c.n_effects; ++k) {
        if (c.effect_kind[k] != 1 && c.effect_kind[k] != 2)
            return dim("effect " + str(k) + ": unknown kind " + str(c.effect_kind[k]) + " (this monitor knows 1 Stribeck, 2 spring)");
        if (c.effect_joint[k] < 0 || c.effect_joint[k] >= c.n_joints) return dim("effect " + str(k) + ": joint out of range");
    }
    std::array<bool, kMaxJoints> seen{};
    for (int i = 0; i < c.n_bodies; ++i) {
        if (c.parent[i] < -1 || c.parent[i] >= i) return dim("body " + str(i) + ": parent must come before it");
        const int t = c.joint_type[i], j = c.joint_index[i];
        if (t < 0 || t > 2) return dim("body " + str(i) + ": unknown joint type " + str(t));
        if (t == 0 ? j != -1 : (j < 0 || j >= c.n_joints || seen[j]))
            return dim("body " + str(i) + ": joint index " + str(j) + " does not fit its joint type");
        if (t != 0) seen[j] = true;
    }
    for (int j = 0; j < c.n_joints; ++j)
        if (!seen[j]) return dim("joint " + str(j) + " moves no body");
    for (int i = 0; i < c.n_outputs; ++i) {
        if (c.channel_kind[i] < 0 || c.channel_kind[i] > 2) return dim("channel " + str(i) + ": unknown kind");
        if ((c.channel_kind[i] == 0) != (i < 6 * c.n_sensors))
            return dim("the six channels of each F/T sensor must come first, and only they");
        if (c.channel_motor[i] < -1 || c.channel_motor[i] >= c.n_motors) return dim("channel " + str(i) + ": motor out of range");
        if ((c.gate_joints[i] >> c.n_joints) != 0 || (c.n_motors < 64 && (c.gate_motors[i] >> c.n_motors) != 0))
            return dim("channel " + str(i) + ": gate names a joint or motor that does not exist");
    }

    // Finite, then physically usable.
    auto nf = [](const char* what) {
        return fail(LoadError::kNotFinite, std::string("non-finite value in ") + what);
    };
    for (int i = 0; i < c.n_bodies; ++i)
        if (!finite_all(c.axis[i]) || !finite_all(c.rotation[i]) || !finite_all(c.translation[i])) return nf("the chain");
    for (int i = 0; i < c.n_bodies; ++i)
        if (!finite_all(c.inertial[i])) return nf("the inertial parameters");
    if (!finite_all(c.gravity)) return nf("gravity");
    for (const auto& l : c.joint_limits)
        if (!finite_all(l)) return nf("the joint limits");
    for (const auto& l : c.fit_range)
        if (!finite_all(l)) return nf("the fit's joint ranges");
    for (int k = 0; k < c.n_motors; ++k)
        if (!finite_all(c.motor_velocity[k]) || !finite_all(c.motor_friction[k])) return nf("the motors");
    for (int j = 0; j < c.n_joints; ++j)
        if (!finite_all(c.joint_friction[j])) return nf("the joint friction");
    for (const auto& o : c.ft_offset)
        if (!finite_all(o)) return nf("the F/T offsets");
    if (!finite_all(c.ft_threshold) || !finite_all(c.accel_tau_variance)) return nf("the detector or filter settings");
    for (int i = 0; i < c.n_outputs; ++i)
        if (!finite_all(c.row_map[i])) return nf("the output rows");
    if (!finite_all(c.divisor) || !finite_all(c.residual_variance)) return nf("the divisors or Λ");
    for (int i = 0; i < 3; ++i)
        if (!finite_all(c.filter[i])) return nf("the derivative filter");
    for (int k = 0; k < c.n_effects; ++k)
        if (!finite_all(c.effect_param[k])) return nf("the effects");
    for (int k = 0; k < c.n_effects; ++k)
        if (c.effect_kind[k] == 1 && !(c.effect_param[k][1] > 0))
            return dim("effect " + str(k) + ": the Stribeck velocity must be positive");
    for (double v : {c.min_speed, c.alpha, c.threshold, c.hysteresis, c.sample_period})
        if (!std::isfinite(v)) return nf("the detector or filter settings");
    if (!std::isfinite(c.supply_time_constant) || !std::isfinite(c.supply_prior) || !finite_all(c.supply_gate))
        return nf("the supply tracking");
    if (c.supply_time_constant < 0 || (c.supply_time_constant > 0 && !(c.supply_prior > 0)))
        return dim("supply tracking: the time constant must be ≥ 0, and the prior positive when it is on");
    for (int i = 0; i < c.n_outputs; ++i)
        if (c.supply_gate[i] < 0 || (c.supply_gate[i] > 0 && c.channel_kind[i] != 1))
            return dim("supply tracking: the gate of " + shown_name(c.channel_names[i]) + " must be ≥ 0, and 0 unless it is a motor input");
    for (int i = 0; i < c.n_outputs; ++i) {
        if (c.residual_variance[i] <= 0) return dim("Λ of " + shown_name(c.channel_names[i]) + " is not positive");
        if (c.divisor[i] == 0) return dim("the divisor (motor gain) of " + shown_name(c.channel_names[i]) + " is zero");
    }
    bool sides = true;
    for (double v : c.ft_threshold) sides = sides && v > 0;
    for (double v : c.accel_tau_variance) sides = sides && v >= 0;
    if (c.threshold <= 0 || !sides || c.hysteresis <= 0 || c.hysteresis > 1 || c.sample_period <= 0 || c.alpha <= 0 ||
        c.alpha >= 1 || c.min_speed < 0)
        return dim("detector settings out of range (thresholds, hysteresis, α, period, τ_ext variances)");
    // The sample clock counts periods between stamps in int64: a period of 1e-300 s overflowed it (fuzzer finding).
    if (c.sample_period < kMinSamplePeriod || c.sample_period > kMaxSamplePeriod) {
        std::ostringstream m;
        m << "sample period " << c.sample_period << " s out of range: " << kMinSamplePeriod << " to " << kMaxSamplePeriod
          << " s";
        return dim(m.str());
    }

    if (LoadResult obs = check_observer(c); !obs) return obs;
    if (LoadResult p = check_plausible(c); !p) return p;

    if (!expected_robot.empty() && c.robot_name != expected_robot)
        return fail(LoadError::kRobot, "exported for robot '" + shown_name(c.robot_name) + "', not for '" + shown_name(expected_robot) + "'");

    // Accepted: copy into fixed storage.
    out = Coefficients{};
    out.robot_name = c.robot_name;
    out.config_digest = c.config_digest;
    out.dynid_version = c.dynid_version;
    out.model_sha256 = c.model_sha256;
    out.data_sha256 = c.data_sha256;
    out.estimator = c.estimator;
    out.n_joints = c.n_joints;
    out.n_bodies = c.n_bodies;
    out.n_motors = c.n_motors;
    out.n_outputs = c.n_outputs;
    for (int i = 0; i < c.n_bodies; ++i) {
        out.parent[i] = c.parent[i];
        out.joint_index[i] = c.joint_index[i];
        out.joint_type[i] = JointType(c.joint_type[i]);
        out.axis[i] = Vec3(c.axis[i][0], c.axis[i][1], c.axis[i][2]);
        out.translation[i] = Vec3(c.translation[i][0], c.translation[i][1], c.translation[i][2]);
        for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k) out.rotation[i](r, k) = c.rotation[i][3 * r + k];
        const Vec3& ax = out.axis[i];
        Mat3 cross;
        cross << 0, -ax.z(), ax.y(), ax.z(), 0, -ax.x(), -ax.y(), ax.x(), 0;
        out.rotation_cross[i] = out.rotation[i] * cross;
        out.rotation_outer[i] = (out.rotation[i] * ax) * ax.transpose();
        const auto& p = c.inertial[i];  // m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz
        out.mass[i] = p[0];
        out.first_moment[i] = Vec3(p[1], p[2], p[3]);
        out.inertia[i] << p[4], p[5], p[7], p[5], p[6], p[8], p[7], p[8], p[9];
    }
    out.gravity = Vec3(c.gravity[0], c.gravity[1], c.gravity[2]);
    out.n_sensors = c.n_sensors;
    out.sensor_of_body.fill(-1);
    for (int i = 0; i < c.n_bodies; ++i) out.body_names[i] = c.body_names[i];
    for (int k = 0; k < c.n_sensors; ++k) {
        out.sensor_body[k] = c.sensor_body[k];
        out.sensor_of_body[c.sensor_body[k]] = k;
        out.sensor_names[k] = c.sensor_names[k];
        for (int m = 0; m < 6; ++m) out.ft_offset[k][m] = c.ft_offset[k][m];
        out.ft_threshold[k] = c.ft_threshold[k];
        out.observer_ft_threshold[k] = c.observer_ft_threshold[k];
    }
    for (int k = 0; k < c.n_motors; ++k) {
        for (int j = 0; j < c.n_joints; ++j) out.motor_velocity(k, j) = c.motor_velocity[k][j];
        out.motor_friction_on[k] = c.motor_friction_on[k] != 0;
        for (int m = 0; m < 4; ++m) out.motor_friction(k, m) = c.motor_friction[k][m];
    }
    for (int j = 0; j < c.n_joints; ++j) {
        out.joint_names[j] = c.joint_names[j];
        out.joint_lower[j] = c.joint_limits[j][0];
        out.joint_upper[j] = c.joint_limits[j][1];
        out.fit_lower[j] = c.fit_range[j][0];
        out.fit_upper[j] = c.fit_range[j][1];
        for (int m = 0; m < 4; ++m) out.joint_friction(j, m) = c.joint_friction[j][m];
    }
    for (int i = 0; i < c.n_outputs; ++i) {
        out.channel_names[i] = c.channel_names[i];
        out.channel_kind[i] = ChannelKind(c.channel_kind[i]);
        for (int j = 0; j < c.n_joints; ++j) out.row_map(i, j) = c.row_map[i][j];
        out.channel_motor[i] = c.channel_motor[i];
        out.divisor[i] = c.divisor[i];
        out.variance[i] = c.residual_variance[i];
        out.gate_joints[i] = uint64_t(c.gate_joints[i]);
        out.gate_motors[i] = uint64_t(c.gate_motors[i]);
        out.supply_gate[i] = c.supply_gate[i];
    }
    out.supply_time_constant = c.supply_time_constant;
    out.supply_prior = c.supply_prior;
    out.min_speed = c.min_speed;
    out.alpha = c.alpha;
    out.threshold = c.threshold;
    out.hysteresis = c.hysteresis;
    out.calibration_samples = c.calibration_samples;
    out.debounce_on = c.debounce_on;
    out.debounce_off = c.debounce_off;
    out.sample_period = c.sample_period;
    out.window = c.window;
    out.order = c.order;
    out.lag = c.lag;
    for (int r = 0; r < 3; ++r)
        for (int i = 0; i < c.window; ++i) out.filter(i, r) = c.filter[r][i];
    out.residual = Residual(c.residual);
    out.observer_bandwidth = c.observer_bandwidth;
    out.velocity_window = c.velocity_window;
    out.measured_velocity = c.observer_velocity == 1;
    for (int i = 0; i < c.velocity_window; ++i) out.velocity_filter[i] = c.velocity_filter[i];
    for (int j = 0; j < c.n_joints; ++j) {
        out.joint_band(j, 0) = c.joint_band[j][0];
        out.joint_band(j, 1) = c.joint_band[j][1];
        out.tau_variance[j] = c.tau_variance[j];
        out.accel_tau_variance[j] = c.accel_tau_variance[j];
        for (int i = 0; i < c.n_outputs; ++i) out.tau_map(j, i) = c.tau_map[j][i];
    }
    for (int k = 0; k < c.n_motors; ++k) {
        out.motor_band(k, 0) = c.motor_band[k][0];
        out.motor_band(k, 1) = c.motor_band[k][1];
    }
    for (int i = 0; i < c.n_outputs; ++i) out.observer_variance[i] = c.observer_variance[i];
    out.observer_threshold = c.observer_threshold;
    out.observer_rest_threshold = c.observer_rest_threshold;
    out.isolation_sigmas = c.isolation_sigmas;
    out.combined_scale = c.combined_scale;
    out.n_effects = c.n_effects;
    for (int k = 0; k < c.n_effects; ++k) {
        out.effect_kind[k] = EffectKind(c.effect_kind[k]);
        out.effect_joint[k] = c.effect_joint[k];
        for (int m = 0; m < 3; ++m) out.effect_param[k][m] = c.effect_param[k][m];
    }
    return check_known_answers(c, out);
}

}  // namespace dynid::rt
