// rt_monitor's LCM messages (publisher.hpp).
#include "rt_monitor/publisher.hpp"

#include <algorithm>
#include <cmath>

#include "rt_monitor/run_stats.hpp"
#include "rt_monitor/status.hpp"

namespace dynid::rt {

Publisher::Publisher(lcm::LCM& lcm, const Coefficients& coef, const Core& core)
    : lcm_(lcm), coef_(coef), core_(core), channels_{"DYNID_CONTACT", "DYNID_RESIDUAL", "DYNID_STATUS"} {
    const int n_out = coef.n_outputs, n_joints = coef.n_joints, n_sensors = coef.n_sensors;
    event_.n_channels = n_out;
    event_.channel.assign(coef.channel_names.begin(), coef.channel_names.begin() + n_out);
    event_.normalized_residual.assign(size_t(n_out), 0.0);
    event_.residual = int8_t(core.residual());  // 0 acceleration, 1 momentum, 2 combined
    event_.n_sensors = n_sensors;
    event_.sensor.assign(coef.sensor_names.begin(), coef.sensor_names.begin() + n_sensors);
    event_.side.assign(size_t(n_sensors), 0);
    event_.wrench.assign(size_t(n_sensors), std::vector<double>(6, 0.0));
    event_.n_joints = n_joints;
    event_.joint.assign(coef.joint_names.begin(), coef.joint_names.begin() + n_joints);
    event_.tau_ext.assign(size_t(n_joints), 0.0);
    event_.beyond_fit.assign(size_t(n_joints), 0);
    event_.isolated_joint = -1;
    event_.threshold = core.threshold();
    // The isolated link's name takes the room of the longest: the event's size never grows in the loop (its string
    // keeps its capacity, the encode buffer is sized for it).
    link_of_joint_.assign(size_t(n_joints), std::string());
    for (int i = 0; i < coef.n_bodies; ++i)
        if (coef.joint_index[size_t(i)] >= 0) link_of_joint_[size_t(coef.joint_index[size_t(i)])] = coef.body_names[size_t(i)];
    size_t longest = 0;
    for (const auto& l : link_of_joint_) longest = std::max(longest, l.size());
    event_.isolated_link.assign(longest, ' ');
    const int event_size = event_.getEncodedSize();
    event_.isolated_link.clear();
    residual_.n_channels = n_out;
    residual_.normalized_residual.assign(size_t(n_out), 0.0);
    residual_.threshold = core.threshold();
    init_supply(coef, status_);  // sized here: the status's encoded size is fixed from here on
    sigma_.resize(size_t(n_out));
    for (int i = 0; i < n_out; ++i) sigma_[size_t(i)] = std::sqrt(core.variance(i));
    wire_.resize(size_t(std::max({event_size, residual_.getEncodedSize(), status_.getEncodedSize()})));
}

template <class Message>
void Publisher::send(Channel channel, const Message& msg) noexcept {
    const int n = msg.encode(wire_.data(), 0, int(wire_.size()));  // < 0 only if a size changed: not sent
    if (n <= 0) {
        ++unencoded_;
        return;
    }
    const long long a0 = allocations();
    const int rc = lcm_.publish(channels_[channel], wire_.data(), unsigned(n));
    publish_allocations_ += allocations() - a0;
    if (rc == 0) ++published_[channel];
    else ++failed_;
}

void Publisher::normalized(std::vector<double>& r, const VecO& e,
                           const std::array<bool, kMaxOutputs>& active) const noexcept {
    for (int i = 0; i < coef_.n_outputs; ++i) r[size_t(i)] = active[size_t(i)] ? e[i] / sigma_[size_t(i)] : 0.0;
}

void Publisher::contact(const Output& o, int64_t t_us, int64_t onset_utime, int64_t peak_utime,
                        int64_t sample, uint64_t beyond_fit, uint32_t faults, int8_t kind) noexcept {
    event_.utime = t_us;
    event_.kind = kind != 0 ? kind : int8_t(o.event);
    event_.onset_utime = onset_utime;
    event_.sample = sample;
    event_.t2 = o.p.t2;
    // The contact's strongest sample so far: an onset's own (the core takes it as the first peak), an end's strongest
    // (at the end's own sample T² is back under the level, and every side unknown), as dynid detect's events take theirs
    const Output::Peak& pk = o.peak;
    event_.peak_utime = peak_utime;
    event_.peak_t2 = pk.t2;
    normalized(event_.normalized_residual, pk.e, pk.active);
    for (int k = 0; k < coef_.n_sensors; ++k) {
        event_.side[size_t(k)] = int8_t(pk.side[size_t(k)]);
        for (int m = 0; m < 6; ++m) event_.wrench[size_t(k)][size_t(m)] = pk.wrench[size_t(k)][m];
    }
    for (int j = 0; j < coef_.n_joints; ++j) {
        event_.tau_ext[size_t(j)] = pk.tau_ext[j];
        event_.beyond_fit[size_t(j)] = int8_t((beyond_fit >> j) & 1u);
    }
    event_.isolated_joint = pk.joint;
    if (pk.joint >= 0) event_.isolated_link.assign(link_of_joint_[size_t(pk.joint)]);  // within its capacity
    else event_.isolated_link.clear();
    event_.faults = int32_t(faults);
    send(kContact, event_);
}

void Publisher::residual(const Output& o, int64_t t_us) noexcept {
    residual_.utime = t_us;
    residual_.t2 = o.p.t2;
    normalized(residual_.normalized_residual, o.p.e, o.p.active);
    send(kResidual, residual_);
}

void Publisher::publish_status(int64_t t_us) noexcept {
    status_.utime = t_us;
    fill_supply(coef_, core_, status_);
    send(kStatus, status_);
}

}  // namespace dynid::rt
