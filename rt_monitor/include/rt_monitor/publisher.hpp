// What rt_monitor publishes on LCM (lcmtypes/, docs/design.md §6): the contact events (DYNID_CONTACT), the decimated
// residual stream (DYNID_RESIDUAL) and the status (DYNID_STATUS). Every message is sized once at start-up, to the
// robot (its sensors, joints, channels, the longest link name), and encoded into one buffer sized then; a publish is
// lcm_publish on that buffer (lcm::LCM::publish(channel, const T*) would allocate per call). Needs the lcm-gen C++
// headers on the include path.
#pragma once

#include <lcm/lcm-cpp.hpp>

#include <cstdint>
#include <string>
#include <vector>

#include "dynid/contact_event_t.hpp"
#include "dynid/monitor_status_t.hpp"
#include "dynid/residual_t.hpp"
#include "rt_monitor/core.hpp"

namespace dynid::rt {

// contact_event_t.kind of a contact cut by a filter restart (the core's events are 1 onset, 2 end)
constexpr int8_t kCutEvent = 3;

class Publisher {
public:
    enum Channel { kContact = 0, kResidual = 1, kStatus = 2 };

    // Start-up: every message sized to the coefficient file and the core's residual (allocates).
    Publisher(lcm::LCM& lcm, const Coefficients& coef, const Core& core);

    // A contact event (onset or end) of the core's output at CAN time t_us, sample `sample` of the run.
    // An event describes o.peak, at peak_utime: an onset's own sample, an end's contact's strongest; `beyond_fit` (bit j)
    // the joints beyond the fit's range there (FitCoverage); `faults` the watchdog's active at publication; `kind` the
    // event's, 0: the core's (o.event).
    void contact(const Output& o, int64_t t_us, int64_t onset_utime, int64_t peak_utime, int64_t sample,
                 uint64_t beyond_fit, uint32_t faults, int8_t kind = 0) noexcept;
    // One sample of the decimated residual stream.
    void residual(const Output& o, int64_t t_us) noexcept;
    // The status, whose counters the caller has filled (status()); the supply ratios are the core's.
    dynid::monitor_status_t& status() noexcept { return status_; }
    void publish_status(int64_t t_us) noexcept;

    int64_t published(Channel c) const noexcept { return published_[c]; }
    int64_t failed() const noexcept { return failed_; }
    int64_t unencoded() const noexcept { return unencoded_; }
    long long allocations_in_publish() const noexcept { return publish_allocations_; }

private:
    template <class Message>
    void send(Channel channel, const Message& msg) noexcept;
    void normalized(std::vector<double>& r, const VecO& e, const std::array<bool, kMaxOutputs>& active) const noexcept;

    lcm::LCM& lcm_;
    const Coefficients& coef_;
    const Core& core_;
    dynid::contact_event_t event_;
    dynid::residual_t residual_;
    dynid::monitor_status_t status_{};
    std::vector<double> sigma_;              // √Λ per channel of the residual that runs, once
    std::vector<std::string> link_of_joint_; // the link each joint moves: the isolated link's name
    std::vector<uint8_t> wire_;              // the one encode buffer
    std::string channels_[3];
    int64_t published_[3] = {}, failed_ = 0, unencoded_ = 0;
    long long publish_allocations_ = 0;      // made inside lcm_publish (the provider's: file:// mallocs one record)
};

}  // namespace dynid::rt
