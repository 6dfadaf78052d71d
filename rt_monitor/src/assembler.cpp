// Sample assembly from the compiled bus table (assembler.hpp): generic over robots, no protocol code.
#include "rt_monitor/assembler.hpp"

#include <cmath>

namespace dynid::rt {

namespace {

int slot_of(const BusTable& b, const std::string& target) {
    for (size_t i = 0; i < b.values.size(); ++i)
        if (b.values[i] == target) return int(i);
    return -1;
}

}  // namespace

bool Assembler::init(const MonitorConfig& cfg, const Coefficients& coef, std::string& error) {
    cfg_ = &cfg;
    const BusTable& b = cfg.bus;
    decoder_.init(b);
    n_joints_ = coef.n_joints;
    n_outputs_ = coef.n_outputs;
    has_dq_ = n_joints_ > 0;
    for (int j = 0; j < n_joints_; ++j) {
        const std::string& name = coef.joint_names[size_t(j)];
        q_slot_[size_t(j)] = slot_of(b, "q." + name);
        dq_slot_[size_t(j)] = slot_of(b, "dq." + name);
        has_dq_ = has_dq_ && dq_slot_[size_t(j)] >= 0;
        if (q_slot_[size_t(j)] < 0) {
            error = "joint " + shown_name(name) + " of the coefficient file is carried by no signal of the "
                    "configuration (target q." + shown_name(name) + ")";
            return false;
        }
        if (coef.measured_velocity && coef.residual != Residual::kAcceleration && dq_slot_[size_t(j)] < 0) {
            error = "the coefficient file's observer takes the robot's measured q̇, and no signal of the configuration "
                    "carries joint " + shown_name(name) + "'s (target dq." + shown_name(name) + ")";
            return false;
        }
    }
    for (int o = 0; o < n_outputs_; ++o) {
        const std::string& name = coef.channel_names[size_t(o)];
        y_slot_[size_t(o)] = slot_of(b, name);
        if (y_slot_[size_t(o)] < 0 || name.rfind("q.", 0) == 0 || name.rfind("dq.", 0) == 0) {
            error = "channel " + shown_name(name) + " of the coefficient file is carried by no signal of the "
                    "configuration";
            return false;
        }
    }
    // Each node's value slots, for its restarts.
    int at = 0;
    for (size_t k = 0; k < b.nodes.size(); ++k) {
        node_first_[k] = at;
        for (const SignalDef& s : b.signals)
            if (s.slot >= 0 && s.target != Target::kSkin && b.frames[size_t(s.frame)].node_index == int(k))
                node_slots_[size_t(at++)] = s.slot;
    }
    node_first_[b.nodes.size()] = at;
    // Every table written once here: its pages are touched at start-up, not in the loop.
    last_seq_.fill(-1);
    last_seen_.fill(-1);
    last_pair_gap_ = -1;
    t_first_.fill(-1);
    slots_.fill(Slot{});
    for (auto& v : first_values_) v.fill(0.0);
    first_saturated_.fill(false);
    scratch_.fill(0.0);
    t_clock_ = t_boundary_ = -1;
    skin_mask_ = 0;
    n_ = MonitorCounters{};
    return true;
}

void Assembler::commit(int frame, const double* v, int64_t t, bool saturated) noexcept {
    const BusTable& b = cfg_->bus;
    const FrameDef& f = b.frames[size_t(frame)];
    for (int i = 0; i < f.n_signals; ++i) {
        const SignalDef& s = b.signals[size_t(f.first_signal + i)];
        if (s.target == Target::kSkin) {
            const uint16_t bit = uint16_t(1u << s.slot);
            skin_mask_ = uint16_t(v[i] != 0 ? skin_mask_ | bit : skin_mask_ & ~bit);
        } else if (s.slot >= 0) {
            slots_[size_t(s.slot)] = Slot{v[i], t, saturated};
        }
    }
}

void Assembler::restart(int node) noexcept {
    ++n_.board_restarts;
    // Values from before the restart are not to be trusted: the next sample waits for fresh ones.
    for (int i = node_first_[size_t(node)]; i < node_first_[size_t(node) + 1]; ++i) slots_[size_t(node_slots_[size_t(i)])].t = -1;
}

bool Assembler::close(int64_t t, Sample& out) noexcept {
    out.t_us = t;
    out.stale = false;
    out.stale_slot = -1;
    out.held = false;
    // A value that came after the previous sample's clock frames is this sample's, however late the sender sent the
    // clock; one that did not is held, and stale once it has been repeated for longer than stale_us.
    auto use = [&](int slot, double& into) {
        const Slot& s = slots_[size_t(slot)];
        into = s.value;
        if (s.t < 0 || (s.t <= t_boundary_ && t - s.t > cfg_->stale_us) || s.saturated) {
            if (!out.stale) out.stale_slot = slot;
            out.stale = true;
        }
        return s.t;
    };
    for (int j = 0; j < n_joints_; ++j) {
        const int64_t tq = use(q_slot_[size_t(j)], out.q[size_t(j)]);
        out.held = out.held || tq <= t_boundary_;
        if (has_dq_) use(dq_slot_[size_t(j)], out.dq[size_t(j)]);
    }
    out.has_dq = has_dq_;
    for (int o = 0; o < n_outputs_; ++o) use(y_slot_[size_t(o)], out.y[size_t(o)]);
    out.skin_mask = skin_mask_;
    ++n_.samples;
    if (out.stale) ++n_.stale_samples;
    return true;
}

bool Assembler::push(const RxFrame& f, Sample& out) noexcept {
    ++n_.frames;
    const canid_t id = f.frame.can_id;
    if (id & CAN_ERR_FLAG) {
        ++n_.error_frames;
        return false;
    }
    const int fi = decoder_.lookup(f.bus, id);
    if (fi < 0) {
        ++n_.unknown_id;
        return false;
    }
    const BusTable& b = cfg_->bus;
    const FrameDef& fr = b.frames[size_t(fi)];
    const int len = f.frame.len;
    if (len != fr.dlc && !(fr.long_dlc && len == fr.long_dlc)) {
        ++n_.bad_length;
        return false;
    }
    last_seen_[size_t(fi)] = f.t_us;
    // Decode every signal; a frame with reserved bits set or a non-finite float is refused whole.
    double* v = scratch_.data();
    bool saturated = false, fault = false, restarted = false;
    int64_t seq = -1;  // a counter of up to 32 bits (the configuration's limit): int64, or 2³¹ up overflows
    const FrameDecoder::Words words = FrameDecoder::words(f.frame.data, len);
    for (int i = 0; i < fr.n_signals; ++i) {
        const SignalDef& s = b.signals[size_t(fr.first_signal + i)];
        if (s.target == Target::kNone) {  // read by nobody
            v[i] = 0;
            continue;
        }
        v[i] = FrameDecoder::value(s, words);
        if (!std::isfinite(v[i]) || (s.target == Target::kReserved && v[i] != 0)) {
            ++n_.bad_length;
            return false;
        }
        saturated |= s.target == Target::kSaturated && v[i] != 0;
        fault |= s.target == Target::kFault && v[i] != 0;
        restarted |= s.target == Target::kRestart && v[i] != 0;
        if (s.target == Target::kSeq) seq = int64_t(v[i]);
    }
    switch (fr.kind) {
        case FrameKind::kClock: ++n_.strain_frames; break;
        case FrameKind::kStatus: ++n_.status_frames; break;
        case FrameKind::kSkin: ++n_.skin_frames; break;
        case FrameKind::kPosition: ++n_.position_frames; break;
        case FrameKind::kSensor: ++n_.sensor_frames; break;
        case FrameKind::kInput: ++n_.pid_frames; break;
    }
    if (saturated) ++n_.saturated;
    if (fault) ++n_.board_faults;
    if (seq >= 0 || restarted) {
        // A restart: the flag, or the counter back at 0 when it was not due to wrap. Not a restart: the same frame
        // again (a duplicate: CAN retransmits a frame whose end was disturbed), a wrap with the frame before it lost
        // (max − 1 then 0), and a duplicate of the flagged frame (its counter is 0 again, as it was).
        int64_t& last = last_seq_[size_t(fi)];
        int64_t wrap = 0;
        for (int i = 0; i < fr.n_signals; ++i)
            if (b.signals[size_t(fr.first_signal + i)].target == Target::kSeq)
                wrap = int64_t((uint64_t(1) << b.signals[size_t(fr.first_signal + i)].length) - 1);
        const bool repeated = seq >= 0 && seq == last;
        if ((restarted && !repeated) || (seq == 0 && last >= 0 && last < wrap - 1 && last != 0)) restart(fr.node_index);
        if (seq >= 0) last = seq;
    }

    const bool clock_pair = fr.pair >= 0 && fr.pair == b.clock_pair;
    if (clock_pair || fi == b.clock) {
        // A clock frame that opens a sample: the clock frame before it closed the previous one (or tried to).
        if (fr.first_half || fr.pair < 0) t_boundary_ = t_clock_;
        t_clock_ = f.t_us;
    }
    if (fr.pair >= 0) {
        const size_t p = size_t(fr.pair);
        int64_t& first = t_first_[p];
        int64_t& unpaired = clock_pair ? n_.unpaired_strain : n_.unpaired_sensor;
        if (fr.first_half) {
            if (first >= 0) ++unpaired;  // the previous first half never got its second
            for (int i = 0; i < fr.n_signals; ++i) first_values_[p][size_t(i)] = v[i];
            first = f.t_us;
            first_saturated_[p] = saturated;
            return false;
        }
        if (first < 0 || f.t_us < first || f.t_us - first > cfg_->pair_us) {
            if (first >= 0) last_pair_gap_ = f.t_us - first;
            ++unpaired;
            if (first >= 0) ++unpaired;  // the stored first half is too old: dropped as well
            first = -1;
            return false;
        }
        const int a = b.pairs[p].first;
        commit(a, first_values_[p].data(), f.t_us, first_saturated_[p] || saturated);
        commit(fi, v, f.t_us, first_saturated_[p] || saturated);
        first = -1;
        return clock_pair ? close(f.t_us, out) : false;
    }
    commit(fi, v, f.t_us, saturated);
    return fi == b.clock ? close(f.t_us, out) : false;
}

}  // namespace dynid::rt
