// Configuration file and sample assembly (assembler.hpp). Payloads are decoded with firmware_like's C codec,
// the same code the board emulators encode with.
#include "rt_monitor/assembler.hpp"

#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <sstream>
#include <tuple>

#include "icub_can.h"

namespace dynid::rt {

namespace {

bool fail(std::string& error, const std::string& path, int line, const std::string& what) {
    error = path + ":" + std::to_string(line) + ": " + escape_control(what);  // a NUL or CR of the file: one line
    return false;
}

int bus_index(const MonitorConfig& c, const std::string& name) {
    for (size_t i = 0; i < c.buses.size(); ++i)
        if (c.buses[i] == name) return int(i);
    return -1;
}

// A whole token as a finite number (strtod's syntax) or a decimal integer; false on anything else.
bool to_number(const std::string& t, double& v) {
    if (t.empty()) return false;
    char* end = nullptr;
    errno = 0;
    v = std::strtod(t.c_str(), &end);
    return *end == '\0' && errno != ERANGE && std::isfinite(v);
}
bool to_integer(const std::string& t, long long& v) {
    if (t.empty()) return false;
    char* end = nullptr;
    errno = 0;
    v = std::strtoll(t.c_str(), &end, 10);
    return *end == '\0' && errno != ERANGE;
}

std::string str(double v) {
    std::ostringstream o;
    o << v;
    return o.str();
}

// What has been read so far, for the duplicate checks: where each single-valued key, joint, motor and board slot
// was first given.
struct Seen {
    std::map<std::string, int> key, joint, motor;
    std::map<std::tuple<int, int, int>, int> axis_slot, pwm_slot;  // (bus, address, slot)
    std::map<std::pair<int, int>, int> skin_board;                 // (bus, address)
};

// One configuration line other than 'buses' (read before all others: keys come in any order), split into tokens
// (`tok[0]` the key). False with `what` naming the problem.
bool parse_line(const std::vector<std::string>& tok, const std::string& raw, int line, MonitorConfig& out, Seen& seen,
                std::string& what) {
    const std::string& key = tok[0];
    const size_t n = tok.size();
    auto bad = [&] {
        what = "bad '" + key + "' line: " + raw;
        return false;
    };
    auto bus = [&](const std::string& name, int& b) {
        b = bus_index(out, name);
        if (b >= 0) return true;
        std::string known;
        for (const auto& x : out.buses) known += " " + x;
        what = "bus '" + name + "' is not in the 'buses' line (" + known.substr(1) + ")";
        return false;
    };
    auto address = [&](const std::string& t, int& a) {
        long long v = 0;
        if (!to_integer(t, v)) return bad();
        if (v < 0 || v > 15) {
            what = "board address must be 0..15";
            return false;
        }
        a = int(v);
        return true;
    };
    auto slot = [&](const std::string& t, int& sl) {
        long long v = 0;
        if (!to_integer(t, v) || (v != 0 && v != 1)) {
            what = "bad '" + key + "' line (the slot is 0 or 1): " + raw;
            return false;
        }
        sl = int(v);
        return true;
    };
    // The value of a one-number setting, within [lo, hi] (`unit` for the message).
    auto setting = [&](double lo, double hi, const char* unit, double& v) {
        if (n != 2 || !to_number(tok[1], v)) return bad();
        if (v < lo || v > hi) {
            what = key + " " + tok[1] + " is out of range: " + str(lo) + " to " + str(hi) + unit;
            return false;
        }
        return true;
    };
    auto integer_setting = [&](long long lo, long long hi, const char* unit, long long& v) {
        if (n != 2) return bad();
        if (!to_integer(tok[1], v)) {  // 1e3, or a whole number beyond long long: its range is the problem
            double d = 0;
            if (!to_number(tok[1], d)) return bad();
            if (d != std::floor(d)) {
                what = key + " must be a whole number, got " + tok[1];
                return false;
            }
            v = d < -9e18 ? LLONG_MIN : d > 9e18 ? LLONG_MAX : (long long)d;
        }
        if (v < lo || v > hi) {
            what = key + " " + tok[1] + " is out of range: " + std::to_string(lo) + " to " + std::to_string(hi) + unit;
            return false;
        }
        return true;
    };

    // Keys given once: a second line is refused, naming the first.
    static const char* kOnce[] = {"robot", "lcm_url", "stale_ms", "pair_us", "status_hz", "residual_every", "strain"};
    for (const char* k : kOnce) {
        if (key != k) continue;
        const auto it = seen.key.find(key);
        if (it != seen.key.end()) {
            what = "a second '" + key + "' line (the first is line " + std::to_string(it->second) + ")";
            return false;
        }
        seen.key[key] = line;
    }

    if (key == "robot") {
        if (n != 2) return bad();
        out.robot = tok[1];
    } else if (key == "lcm_url") {
        if (n != 2) return bad();
        out.lcm_url = tok[1];
    } else if (key == "stale_ms") {
        double ms = 0;
        if (!setting(kStaleMsMin, kStaleMsMax, " ms", ms)) return false;
        out.stale_us = int64_t(std::llround(ms * 1000));
    } else if (key == "pair_us") {
        long long v = 0;
        if (!integer_setting(kPairUsMin, kPairUsMax, " µs", v)) return false;
        out.pair_us = v;
    } else if (key == "status_hz") {
        if (!setting(kStatusHzMin, kStatusHzMax, " Hz", out.status_hz)) return false;
    } else if (key == "residual_every") {
        long long v = 0;
        if (!integer_setting(1, kResidualEveryMax, " samples", v)) return false;
        out.residual_every = int(v);
    } else if (key == "strain") {
        if (n != 9) return bad();
        if (!bus(tok[1], out.strain_bus) || !address(tok[2], out.strain_address)) return false;
        for (size_t k = 0; k < 6; ++k) {
            if (!to_number(tok[3 + k], out.full_scale[k])) return bad();
            if (!(out.full_scale[k] > 0 && out.full_scale[k] <= kFullScaleMax)) {
                what = "strain full scale " + tok[3 + k] + " is out of range: above 0, at most " + str(kFullScaleMax);
                return false;
            }
        }
    } else if (key == "axis" || key == "pwm") {
        const bool is_axis = key == "axis";
        if (n != (is_axis ? 7u : 6u)) return bad();
        int b = 0, a = 0, sl = 0;
        if (!bus(tok[1], b) || !address(tok[2], a) || !slot(tok[3], sl)) return false;
        const std::string& name = tok[4];
        double v1 = 0, v2 = 0;
        if (!to_number(tok[5], v1) || (is_axis && !to_number(tok[6], v2))) return bad();
        if (is_axis && !(v1 >= kTicksPerDegreeMin && v1 <= kTicksPerDegreeMax)) {
            what = "ticks per degree " + tok[5] + " is out of range: " + str(kTicksPerDegreeMin) + " to " +
                   str(kTicksPerDegreeMax);
            return false;
        }
        if (is_axis && !(std::fabs(v2) <= kZeroDegMax)) {
            what = "zero " + tok[6] + " is out of range: -" + str(kZeroDegMax) + " to " + str(kZeroDegMax) + " degrees";
            return false;
        }
        if (!is_axis && !(v1 > 0 && v1 <= kPwmFullScaleMax)) {
            what = "PWM full scale " + tok[5] + " is out of range: above 0, at most " + str(kPwmFullScaleMax);
            return false;
        }
        auto& names = is_axis ? seen.joint : seen.motor;
        auto& slots = is_axis ? seen.axis_slot : seen.pwm_slot;
        const auto named = names.find(name);
        if (named != names.end()) {
            what = std::string(is_axis ? "joint" : "motor") + " '" + name + "' has a second '" + key +
                   "' line (the first is line " + std::to_string(named->second) + ")";
            return false;
        }
        const auto used = slots.find({b, a, sl});
        if (used != slots.end()) {
            what = "board " + tok[1] + " " + tok[2] + " slot " + tok[3] + " has a second '" + key +
                   "' line (the first is line " + std::to_string(used->second) + ")";
            return false;
        }
        names[name] = line;
        slots[{b, a, sl}] = line;
        if (is_axis) {
            AxisMap m;
            m.bus = b, m.address = a, m.slot = sl, m.joint = name, m.ticks_per_degree = v1, m.zero_deg = v2;
            out.axes.push_back(m);
        } else {
            PwmMap m;
            m.bus = b, m.address = a, m.slot = sl, m.motor = name, m.full_scale = v1;
            out.pwms.push_back(m);
        }
    } else if (key == "skin") {
        MonitorConfig::Skin k;
        if (n != 5) return bad();
        if (!bus(tok[1], k.bus) || !address(tok[2], k.address)) return false;
        k.patch = tok[3];
        k.side = tok[4];
        if (k.side != "distal" && k.side != "proximal") {
            what = "skin side must be distal or proximal, got '" + k.side + "'";
            return false;
        }
        const auto used = seen.skin_board.find({k.bus, k.address});
        if (used != seen.skin_board.end()) {
            what = "skin board " + tok[1] + " " + tok[2] + " has a second 'skin' line (the first is line " +
                   std::to_string(used->second) + ")";
            return false;
        }
        if (out.skins.size() == size_t(kMaxSkins)) {
            what = "more than " + std::to_string(kMaxSkins) + " skin boards";
            return false;
        }
        seen.skin_board[{k.bus, k.address}] = line;
        out.skins.push_back(k);
    } else {
        what = "unknown key '" + key + "'";
        return false;
    }
    return true;
}

}  // namespace

bool parse_monitor_config(const std::string& text, const std::string& path, MonitorConfig& out, std::string& error) {
    out = MonitorConfig{};
    std::vector<std::string> lines;
    {
        std::istringstream in(text);
        for (std::string raw; std::getline(in, raw);) lines.push_back(raw);
    }
    // Tokens of line i, comment stripped.
    auto tokens = [&](size_t i) {
        std::istringstream s(lines[i].substr(0, lines[i].find('#')));
        std::vector<std::string> tok;
        for (std::string t; s >> t;) tok.push_back(t);
        return tok;
    };
    // The 'buses' line first, then every other line in file order: keys come in any order (repeated keys keep
    // theirs: the n-th skin line is skin board n).
    int buses_line = 0;
    for (size_t i = 0; i < lines.size(); ++i) {
        const std::vector<std::string> tok = tokens(i);
        if (tok.empty() || tok[0] != "buses") continue;
        const int ln = int(i) + 1;
        if (buses_line)
            return fail(error, path, ln, "a second 'buses' line (the first is line " + std::to_string(buses_line) + ")");
        for (size_t k = 1; k < tok.size(); ++k) {
            if (bus_index(out, tok[k]) >= 0) return fail(error, path, ln, "bus '" + tok[k] + "' named twice");
            out.buses.push_back(tok[k]);
        }
        if (out.buses.empty() || out.buses.size() > size_t(kMaxBuses))
            return fail(error, path, ln, "bad 'buses' line (1 to 8 bus names): " + lines[i]);
        buses_line = ln;
    }
    if (!buses_line) return fail(error, path, 0, "no 'buses' line");
    Seen seen;
    for (size_t i = 0; i < lines.size(); ++i) {
        const std::vector<std::string> tok = tokens(i);
        std::string what;
        if (tok.empty() || tok[0] == "buses") continue;
        if (!parse_line(tok, lines[i], int(i) + 1, out, seen, what)) return fail(error, path, int(i) + 1, what);
    }
    if (!seen.key.count("robot"))
        return fail(error, path, 0, "no 'robot' line (the coefficient file's robot is checked against it)");
    if (!seen.key.count("strain")) return fail(error, path, 0, "no 'strain' line");
    return true;
}

bool load_monitor_config(const std::string& path, MonitorConfig& out, std::string& error) {
    // stdio, so that a read error is one (a directory read as an ifstream was an empty file: "no 'buses' line").
    constexpr size_t kMaxBytes = size_t(1) << 20;  // a configuration is a few hundred bytes; /dev/zero is not one
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) return fail(error, path, 0, std::string("cannot open the configuration: ") + std::strerror(errno));
    std::string text;
    char block[4096];
    size_t n = 0;
    while ((n = std::fread(block, 1, sizeof block, f)) > 0 && text.size() <= kMaxBytes) text.append(block, n);
    const int read_errno = std::ferror(f) ? errno : 0;
    std::fclose(f);
    if (read_errno) return fail(error, path, 0, std::string("cannot read the configuration: ") + std::strerror(read_errno));
    if (text.size() > kMaxBytes) return fail(error, path, 0, "larger than 1 MB: not a monitor configuration");
    return parse_monitor_config(text, path, out, error);
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
            error = "joint " + shown_name(coef.joint_names[size_t(j)]) +
                    " of the coefficient file has no 'axis' line in the configuration";
            return false;
        }
    }
    static const char* kFt[6] = {"fx", "fy", "fz", "tx", "ty", "tz"};
    for (int o = 0; o < n_outputs_; ++o) {
        const std::string& name = coef.channel_names[size_t(o)];
        int src = -1;
        for (int k = 0; k < 6; ++k)
            if (coef.n_sensors > 0 && name == "ft." + coef.sensor_names[0] + "." + kFt[k]) src = k;
        for (size_t p = 0; p < cfg.pwms.size(); ++p)
            if (name == "pwm." + cfg.pwms[p].motor) src = 6 + int(p);
        if (src < 0) {
            error = "channel " + shown_name(name) + " of the coefficient file is served by no board of the configuration";
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
        ++n_.strain_frames;
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
        ++n_.position_frames;
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
        ++n_.pid_frames;
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
        ++n_.status_frames;
        if (f0 | f1) ++n_.board_faults;
        int& last = status_seq_[size_t(f.bus * 16 + src)];
        // A restart: the flag, or the counter back at 0 when it was not due to wrap. Not a restart: the same frame
        // again (a duplicate: CAN retransmits a frame whose end was disturbed; seq 0 twice), a wrap with the frame of
        // 255 lost (254 then 0), and a duplicate of the flagged frame (its counter is 0 again, as it was).
        const bool repeated = seq == last;
        if (((b & ICUB_CAN_MC_BOARD_RESTARTED) && !repeated) || (last >= 0 && seq == 0 && last < 254 && last != 0)) {
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
