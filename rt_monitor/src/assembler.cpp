// Configuration file and sample assembly (assembler.hpp). Payloads are decoded with firmware_like's C codec,
// the same code the board emulators encode with.
#include "rt_monitor/assembler.hpp"

#include <cmath>
#include <fstream>
#include <sstream>

#include "icub_can.h"

namespace dynid::rt {

namespace {

bool fail(std::string& error, const std::string& path, int line, const std::string& what) {
    error = path + ":" + std::to_string(line) + ": " + what;
    return false;
}

int bus_index(const MonitorConfig& c, const std::string& name) {
    for (size_t i = 0; i < c.buses.size(); ++i)
        if (c.buses[i] == name) return int(i);
    return -1;
}

// One configuration line other than 'buses' (read before all others: keys come in any order), its key read
// from `s`. False with `what` naming the problem.
bool parse_line(const std::string& key, std::istringstream& s, const std::string& raw, MonitorConfig& out,
                bool& have_strain, std::string& what) {
    std::string bad_bus;
    auto bus = [&](int& b) {
        std::string name;
        if (!(s >> name)) return false;
        b = bus_index(out, name);
        if (b < 0) bad_bus = name;
        return b >= 0;
    };
    int address = 1;  // the board address this line names, if any
    bool ok = true;
    if (key == "robot") {
        ok = bool(s >> out.robot);
    } else if (key == "lcm_url") {
        ok = bool(s >> out.lcm_url);
    } else if (key == "stale_ms") {
        double ms = 0;
        ok = bool(s >> ms) && ms > 0;
        out.stale_us = int64_t(std::llround(ms * 1000));
    } else if (key == "pair_us") {
        ok = bool(s >> out.pair_us) && out.pair_us > 0;
    } else if (key == "status_hz") {
        ok = bool(s >> out.status_hz) && out.status_hz > 0;
    } else if (key == "residual_every") {
        ok = bool(s >> out.residual_every) && out.residual_every > 0;
    } else if (key == "strain") {
        ok = bus(out.strain_bus) && bool(s >> out.strain_address);
        for (double& fs : out.full_scale) ok = ok && bool(s >> fs) && fs > 0 && std::isfinite(fs);
        address = out.strain_address;
        have_strain = true;
    } else if (key == "axis") {
        AxisMap a;
        ok = bus(a.bus) && bool(s >> a.address >> a.slot >> a.joint >> a.ticks_per_degree >> a.zero_deg) &&
             a.ticks_per_degree > 0 && (a.slot == 0 || a.slot == 1);
        address = a.address;
        out.axes.push_back(a);
    } else if (key == "pwm") {
        PwmMap p;
        ok = bus(p.bus) && bool(s >> p.address >> p.slot >> p.motor >> p.full_scale) && p.full_scale > 0 &&
             (p.slot == 0 || p.slot == 1);
        address = p.address;
        out.pwms.push_back(p);
    } else if (key == "skin") {
        MonitorConfig::Skin k;
        ok = bus(k.bus) && bool(s >> k.address >> k.patch >> k.side) && (k.side == "distal" || k.side == "proximal");
        address = k.address;
        out.skins.push_back(k);
    } else {
        what = "unknown key '" + key + "'";
        return false;
    }
    std::string extra;
    if (!bad_bus.empty()) {
        std::string known;
        for (const auto& b : out.buses) known += " " + b;
        what = "bus '" + bad_bus + "' is not in the 'buses' line (" + known.substr(1) + ")";
    } else if (!ok || (s >> extra)) {
        what = "bad '" + key + "' line: " + raw;
    } else if (address < 0 || address > 15) {
        what = "board address must be 0..15";
    }
    return what.empty();
}

}  // namespace

bool load_monitor_config(const std::string& path, MonitorConfig& out, std::string& error) {
    std::ifstream in(path);
    if (!in) return fail(error, path, 0, "cannot open the configuration");
    out = MonitorConfig{};
    std::vector<std::string> lines;
    for (std::string raw; std::getline(in, raw);) lines.push_back(raw);
    auto content = [&](size_t i) { return std::istringstream(lines[i].substr(0, lines[i].find('#'))); };
    // The 'buses' line first, then every other line in file order: keys come in any order (repeated keys keep
    // theirs: the n-th skin line is skin board n).
    int buses_line = 0;
    for (size_t i = 0; i < lines.size(); ++i) {
        std::istringstream s = content(i);
        std::string key;
        if (!(s >> key) || key != "buses") continue;
        const int ln = int(i) + 1;
        if (buses_line)
            return fail(error, path, ln, "a second 'buses' line (the first is line " + std::to_string(buses_line) + ")");
        for (std::string b; s >> b;) {
            if (bus_index(out, b) >= 0) return fail(error, path, ln, "bus '" + b + "' named twice");
            out.buses.push_back(b);
        }
        if (out.buses.empty() || out.buses.size() > 8)
            return fail(error, path, ln, "bad 'buses' line (1 to 8 bus names): " + lines[i]);
        buses_line = ln;
    }
    if (!buses_line) return fail(error, path, 0, "no 'buses' line");
    bool have_strain = false;
    for (size_t i = 0; i < lines.size(); ++i) {
        std::istringstream s = content(i);
        std::string key, what;
        if (!(s >> key) || key == "buses") continue;
        if (!parse_line(key, s, lines[i], out, have_strain, what)) return fail(error, path, int(i) + 1, what);
    }
    if (!have_strain) return fail(error, path, 0, "no 'strain' line");
    if (out.skins.size() > 16) return fail(error, path, 0, "at most 16 skin boards");
    return true;
}

int Assembler::board(int bus, unsigned cls, unsigned address) const noexcept {
    if (bus < 0 || bus >= kMaxBus) return 0;
    return boards_[size_t((bus * 8 + int(cls)) * 16 + int(address))];
}

bool Assembler::init(const MonitorConfig& cfg, const Coefficients& coef, std::string& error) {
    cfg_ = &cfg;
    n_joints_ = coef.n_joints;
    n_outputs_ = coef.n_outputs;
    auto set = [&](int bus, unsigned cls, int address, int value) {
        boards_[size_t((bus * 8 + int(cls)) * 16 + address)] = int16_t(value);
    };
    set(cfg.strain_bus, ICUB_CAN_CLASS_STRAIN, cfg.strain_address, 1);
    for (const auto& a : cfg.axes) set(a.bus, ICUB_CAN_CLASS_MC, a.address, 1);
    for (const auto& p : cfg.pwms) set(p.bus, ICUB_CAN_CLASS_MC, p.address, 1);
    for (size_t i = 0; i < cfg.skins.size(); ++i) set(cfg.skins[i].bus, ICUB_CAN_CLASS_SKIN, cfg.skins[i].address, int(i) + 1);
    for (int j = 0; j < n_joints_; ++j) {
        joint_axis_[size_t(j)] = -1;
        for (size_t a = 0; a < cfg.axes.size(); ++a)
            if (cfg.axes[a].joint == coef.joint_names[size_t(j)]) joint_axis_[size_t(j)] = int(a);
        if (joint_axis_[size_t(j)] < 0) {
            error = "joint " + coef.joint_names[size_t(j)] + " of the coefficient file has no 'axis' line in the configuration";
            return false;
        }
    }
    static const char* kFt[6] = {"fx", "fy", "fz", "tx", "ty", "tz"};
    for (int o = 0; o < n_outputs_; ++o) {
        const std::string& name = coef.channel_names[size_t(o)];
        int src = -1;
        for (int k = 0; k < 6; ++k)
            if (name == "ft." + coef.sensor_name + "." + kFt[k]) src = k;
        for (size_t p = 0; p < cfg.pwms.size(); ++p)
            if (name == "pwm." + cfg.pwms[p].motor) src = 6 + int(p);
        if (src < 0) {
            error = "channel " + name + " of the coefficient file is served by no board of the configuration";
            return false;
        }
        out_src_[size_t(o)] = src;
    }
    q_.assign(cfg.axes.size(), 0.0);
    t_q_.assign(cfg.axes.size(), -1);
    pwm_.assign(cfg.pwms.size(), 0.0);
    t_pwm_.assign(cfg.pwms.size(), -1);
    status_seq_.assign(size_t(kMaxBus) * 16, -1);
    return true;
}

bool Assembler::push(const RxFrame& f, Sample& out) noexcept {
    ++n_.frames;
    const canid_t id = f.frame.can_id;
    if (id & CAN_ERR_FLAG) {
        ++n_.error_frames;
        return false;
    }
    uint8_t cls = 0, src = 0, type = 0;
    if ((id & (CAN_EFF_FLAG | CAN_RTR_FLAG)) || icub_can_id_split(uint16_t(id & CAN_SFF_MASK), &cls, &src, &type) != 0 ||
        board(f.bus, cls, src) == 0) {
        ++n_.unknown_id;
        return false;
    }
    const uint8_t* d = f.frame.data;
    const uint8_t len = f.frame.len;
    if (cls == ICUB_CAN_CLASS_STRAIN && (type == ICUB_CAN_STRAIN_FORCE || type == ICUB_CAN_STRAIN_TORQUE)) {
        int16_t s[3];
        uint8_t flags = 0;
        if (icub_can_strain_unpack(d, len, s, &flags) != ICUB_CAN_OK) {
            ++n_.bad_length;
            return false;
        }
        if (flags) ++n_.saturated;
        const int base = type == ICUB_CAN_STRAIN_FORCE ? 0 : 3;
        // A force half opens a sample: the strain frame before it closed the previous one (or tried to).
        if (type == ICUB_CAN_STRAIN_FORCE) t_boundary_ = t_strain_;
        t_strain_ = f.t_us;
        if (type == ICUB_CAN_STRAIN_FORCE) {
            if (t_force_ >= 0) ++n_.unpaired_strain;  // the previous force half never got its torque half
            for (int k = 0; k < 3; ++k) force_[size_t(k)] = icub_can_strain_value(s[k], cfg_->full_scale[size_t(k)]);
            t_force_ = f.t_us;
            force_saturated_ = flags != 0;
            return false;
        }
        if (t_force_ < 0 || f.t_us < t_force_ || f.t_us - t_force_ > cfg_->pair_us) {
            ++n_.unpaired_strain;
            if (t_force_ >= 0) ++n_.unpaired_strain;  // the stored force half is too old: dropped as well
            t_force_ = -1;
            return false;
        }
        std::array<double, 6> w{};
        for (int k = 0; k < 3; ++k) {
            w[size_t(k)] = force_[size_t(k)];
            w[size_t(base + k)] = icub_can_strain_value(s[k], cfg_->full_scale[size_t(base + k)]);
        }
        out.t_us = f.t_us;
        out.stale = force_saturated_ || flags != 0;
        t_force_ = -1;
        // A value that came after the previous sample's strain frames is this sample's, however late the sender
        // sent the pair (a sender preempted between its frames stamps them far apart); one that did not is held,
        // and stale once it has been repeated for longer than stale_us.
        out.held = false;
        auto old = [&](int64_t t) { return t < 0 || (t <= t_boundary_ && out.t_us - t > cfg_->stale_us); };
        for (int j = 0; j < n_joints_; ++j) {
            const int a = joint_axis_[size_t(j)];
            out.q[size_t(j)] = q_[size_t(a)];
            const int64_t t = t_q_[size_t(a)];
            out.held = out.held || t <= t_boundary_;
            if (old(t)) out.stale = true;
        }
        for (int o = 0; o < n_outputs_; ++o) {
            const int s6 = out_src_[size_t(o)];
            if (s6 < 6) {
                out.y[size_t(o)] = w[size_t(s6)];
            } else {
                out.y[size_t(o)] = pwm_[size_t(s6 - 6)];
                if (old(t_pwm_[size_t(s6 - 6)])) out.stale = true;
            }
        }
        out.skin_mask = skin_mask_;
        ++n_.samples;
        if (out.stale) ++n_.stale_samples;
        return true;
    }
    if (cls == ICUB_CAN_CLASS_MC && type == ICUB_CAN_MC_POSITION) {
        int32_t v[2];
        if (icub_can_mc_position_unpack(d, len, &v[0], &v[1]) != ICUB_CAN_OK) {
            ++n_.bad_length;
            return false;
        }
        for (size_t a = 0; a < cfg_->axes.size(); ++a) {
            const AxisMap& m = cfg_->axes[a];
            if (m.bus != f.bus || m.address != src) continue;
            q_[a] = (double(v[m.slot]) / m.ticks_per_degree - m.zero_deg) * (M_PI / 180.0);
            t_q_[a] = f.t_us;
        }
        return false;
    }
    if (cls == ICUB_CAN_CLASS_MC && type == ICUB_CAN_MC_PID_VAL) {
        int16_t v[2];
        if (icub_can_mc_pid_val_unpack(d, len, &v[0], &v[1]) != ICUB_CAN_OK) {
            ++n_.bad_length;
            return false;
        }
        for (size_t p = 0; p < cfg_->pwms.size(); ++p) {
            const PwmMap& m = cfg_->pwms[p];
            if (m.bus != f.bus || m.address != src) continue;
            pwm_[p] = double(v[m.slot]) / m.full_scale;
            t_pwm_[p] = f.t_us;
        }
        return false;
    }
    if (cls == ICUB_CAN_CLASS_MC && type == ICUB_CAN_MC_STATUS) {
        uint8_t f0 = 0, f1 = 0, b = 0, seq = 0;
        if (icub_can_mc_status_unpack(d, len, &f0, &f1, &b, &seq) != ICUB_CAN_OK) {
            ++n_.bad_length;
            return false;
        }
        if (f0 | f1) ++n_.board_faults;
        int& last = status_seq_[size_t(f.bus * 16 + src)];
        // A restart: the flag, or the counter back at 0 when it was not due to wrap.
        if ((b & ICUB_CAN_MC_BOARD_RESTARTED) || (last >= 0 && seq == 0 && last != 255)) {
            ++n_.board_restarts;
            // Values from before the restart are not to be trusted: the next sample waits for fresh ones.
            for (size_t a = 0; a < cfg_->axes.size(); ++a)
                if (cfg_->axes[a].bus == f.bus && cfg_->axes[a].address == src) t_q_[a] = -1;
            for (size_t p = 0; p < cfg_->pwms.size(); ++p)
                if (cfg_->pwms[p].bus == f.bus && cfg_->pwms[p].address == src) t_pwm_[p] = -1;
        }
        last = seq;
        return false;
    }
    if (cls == ICUB_CAN_CLASS_SKIN && type == ICUB_CAN_SKIN_TAXELS) {
        uint16_t taxels = 0;
        if (icub_can_skin_unpack(d, len, &taxels) != ICUB_CAN_OK) {
            ++n_.bad_length;
            return false;
        }
        ++n_.skin_frames;
        const int k = board(f.bus, cls, src) - 1;
        skin_mask_ = uint16_t(taxels ? skin_mask_ | (1u << k) : skin_mask_ & ~(1u << k));
        return false;
    }
    ++n_.unknown_id;  // a configured board, but a type it does not send
    return false;
}

}  // namespace dynid::rt
