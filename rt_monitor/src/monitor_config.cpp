// The monitor's configuration file and its compiled bus table (monitor_config.hpp, bus_table.hpp): parsed once at
// start-up; every refusal is one line naming the file, the line and the problem.
#include "rt_monitor/monitor_config.hpp"

#include "signal_plausibility.hpp"

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <sstream>

#include "rt_monitor/coefficients.hpp"  // escape_control

namespace dynid::rt {

namespace {

// line 0: the file as a whole (a line it lacks). A NUL or CR of the file stays on one line.
bool fail(std::string& error, const std::string& path, int line, const std::string& what) {
    error = path + (line > 0 ? ":" + std::to_string(line) : std::string()) + ": " + escape_control(what);
    return false;
}

int index_of(const std::vector<std::string>& names, const std::string& name) {
    const auto it = std::find(names.begin(), names.end(), name);
    return it == names.end() ? -1 : int(it - names.begin());
}

// A whole token as a finite number (strtod's syntax) or an integer (decimal, or hex with 0x); false on anything else.
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
    const bool hex = t.size() > 2 && t[0] == '0' && (t[1] == 'x' || t[1] == 'X');
    v = std::strtoll(t.c_str(), &end, hex ? 16 : 10);
    return *end == '\0' && errno != ERANGE && !(hex && t.size() == 2);
}

std::string str(double v) {
    std::ostringstream o;
    o << v;
    return o.str();
}

bool value_family(const std::string& family, Target& t) {
    static const std::pair<const char*, Target> kFamilies[] = {{"q", Target::kQ}, {"dq", Target::kDq},
        {"pwm", Target::kPwm}, {"current", Target::kCurrent}, {"tau", Target::kTau}, {"ft", Target::kFt}};
    for (const auto& [name, kind] : kFamilies)
        if (family == name) return t = kind, true;
    return false;
}

// A value target: q.J, dq.J, pwm.M, current.M, tau.J or ft.S.C (C one of fx fy fz tx ty tz).
bool value_target(const std::string& text, Target& t) {
    const size_t dot = text.find('.');
    if (dot == std::string::npos || dot + 1 == text.size() || !value_family(text.substr(0, dot), t)) return false;
    if (t != Target::kFt) return true;
    const size_t last = text.rfind('.');
    static const char* kFt[] = {"fx", "fy", "fz", "tx", "ty", "tz"};
    if (last == dot) return false;
    for (const char* c : kFt)
        if (text.compare(last + 1, std::string::npos, c) == 0) return true;
    return false;
}

// The bits a signal occupies, as a mask over byte·8 + bit; false if it leaves the 8-byte payload.
bool signal_bits(int start, int length, bool big_endian, uint64_t& mask, int& end_byte) {
    mask = 0;
    int pos = start;
    for (int i = 0; i < length; ++i) {
        if (pos < 0 || pos > 63) return false;
        mask |= uint64_t(1) << pos;
        end_byte = std::max(end_byte, pos / 8 + 1);
        pos = big_endian ? (pos % 8 ? pos - 1 : pos + 15) : pos + 1;
    }
    return true;
}

struct Parser {
    Parser(const std::string& p, MonitorConfig& o) : path(p), out(o) {}
    const std::string& path;
    MonitorConfig& out;
    std::string what;
    std::map<std::string, int> once;             // single-valued key -> its line
    std::vector<int> frame_line, patch_line;
    std::map<std::pair<int, uint32_t>, int> ids;  // (bus, ID) -> frame
    std::map<std::string, int> value_line;        // value target -> the line carrying it
    std::vector<uint64_t> used_bits;              // per frame
    std::vector<std::vector<SignalDef>> signals;  // per frame, in file order
    std::vector<int> signal_lines;
    std::vector<uint8_t> frame_flags;             // per frame: 1 restart given, 2 seq given

    bool bad(const std::string& raw, const std::string& key) {
        what = "bad '" + key + "' line: " + raw;
        return false;
    }
    bool first_time(const std::string& key, int line) {
        const auto it = once.find(key);
        if (it != once.end()) {
            what = "a second '" + key + "' line (the first is line " + std::to_string(it->second) + ")";
            return false;
        }
        once[key] = line;
        return true;
    }
    bool integer(const std::string& t, long long lo, long long hi, const char* name, long long& v) {
        if (!to_integer(t, v) || v < lo || v > hi) {
            what = std::string(name) + " must be an integer " + std::to_string(lo) + " to " + std::to_string(hi) +
                   ", got '" + t + "'";
            return false;
        }
        return true;
    }
    int frame_index(const std::string& name) {
        for (size_t i = 0; i < out.bus.frames.size(); ++i)
            if (out.bus.frames[i].name == name) return int(i);
        what = "frame '" + name + "' is not defined by a 'frame' line";
        return -1;
    }

    bool frame(const std::vector<std::string>& tok, const std::string& raw, int line) {
        if (tok.size() != 9) return bad(raw, "frame");
        FrameDef f;
        f.name = tok[1];
        for (size_t i = 0; i < out.bus.frames.size(); ++i)
            if (out.bus.frames[i].name == f.name) {
                what = "a second frame '" + f.name + "' (the first is line " + std::to_string(frame_line[i]) + ")";
                return false;
            }
        if (out.bus.frames.size() == size_t(kMaxFrames)) {
            what = "more than " + std::to_string(kMaxFrames) + " frames (kMaxFrames, rt_monitor/capacity.hpp)";
            return false;
        }
        f.bus = index_of(out.buses, tok[2]);
        if (f.bus < 0) {
            std::string known;
            for (const auto& x : out.buses) known += " " + x;
            what = "bus '" + tok[2] + "' is not in the 'buses' line (" + known.substr(1) + ")";
            return false;
        }
        long long id = 0, dlc = 0, long_dlc = 0, period = 0, offset = 0;
        if (!integer(tok[3], 0, 0x7FF, "a frame's ID (11-bit, standard)", id) ||
            !integer(tok[4], 0, 8, "a frame's DLC", dlc) || !integer(tok[5], 0, 8, "a frame's long DLC", long_dlc) ||
            !integer(tok[7], 0, kPeriodUsMax, "a frame's period in µs", period) ||
            !integer(tok[8], kOffsetUsMin, 0, "a frame's send offset in µs", offset))
            return false;
        if (long_dlc != 0 && long_dlc <= dlc) {
            what = "the long DLC " + tok[5] + " must be above the DLC " + tok[4] + " (or 0: no long form)";
            return false;
        }
        const auto seen = ids.find({f.bus, uint32_t(id)});
        if (seen != ids.end()) {
            what = "ID " + tok[3] + " on " + tok[2] + " is frame '" + out.bus.frames[size_t(seen->second)].name +
                   "''s already (line " + std::to_string(frame_line[size_t(seen->second)]) + ")";
            return false;
        }
        ids[{f.bus, uint32_t(id)}] = int(out.bus.frames.size());
        f.id = uint32_t(id), f.dlc = int(dlc), f.long_dlc = int(long_dlc), f.period_us = period, f.offset_us = offset;
        f.node = tok[6];
        f.node_index = index_of(out.bus.nodes, f.node);
        if (f.node_index < 0) {
            f.node_index = int(out.bus.nodes.size());
            out.bus.nodes.push_back(f.node);
        }
        out.bus.frames.push_back(f);
        frame_line.push_back(line);
        used_bits.push_back(0);
        signals.emplace_back();
        frame_flags.push_back(0);
        return true;
    }

    bool patch(const std::vector<std::string>& tok, const std::string& raw, int line) {
        if (tok.size() < 2) return bad(raw, "patch");
        PatchDef p;
        p.name = tok[1];
        for (size_t i = 0; i < out.bus.patches.size(); ++i)
            if (out.bus.patches[i].name == p.name) {
                what = "a second patch '" + p.name + "' (the first is line " + std::to_string(patch_line[i]) + ")";
                return false;
            }
        if (out.bus.patches.size() == size_t(kMaxSkins)) {
            what = "more than " + std::to_string(kMaxSkins) + " skin patches (kMaxSkins, rt_monitor/capacity.hpp)";
            return false;
        }
        for (size_t k = 2; k < tok.size(); ++k) {
            const size_t colon = tok[k].find(':');
            const std::string side = colon == std::string::npos ? "" : tok[k].substr(colon + 1);
            if (colon == 0 || (side != "distal" && side != "proximal")) {
                what = "a patch's side is SENSOR:distal or SENSOR:proximal, got '" + tok[k] + "'";
                return false;
            }
            p.sides.emplace_back(tok[k].substr(0, colon), side);
        }
        out.bus.patches.push_back(p);
        patch_line.push_back(line);
        return true;
    }

    bool signal(const std::vector<std::string>& tok, const std::string& raw, int line) {
        if (tok.size() != 9) return bad(raw, "signal");
        const int fi = frame_index(tok[1]);
        if (fi < 0) return false;
        if (signal_lines.size() >= size_t(kMaxSignals)) {
            what = "more than " + std::to_string(kMaxSignals) + " signals (kMaxSignals, rt_monitor/capacity.hpp)";
            return false;
        }
        FrameDef& f = out.bus.frames[size_t(fi)];
        SignalDef s;
        s.frame = fi;
        long long start = 0, length = 0;
        if (!integer(tok[2], 0, 63, "a signal's start bit", start) || !integer(tok[3], 1, 64, "a signal's length", length))
            return false;
        s.start = int(start), s.length = int(length);
        if (tok[4] != "le" && tok[4] != "be") {
            what = "a signal's byte order is le (Intel) or be (Motorola), got '" + tok[4] + "'";
            return false;
        }
        s.big_endian = tok[4] == "be";
        if (tok[5] == "u") s.type = SignalType::kUnsigned;
        else if (tok[5] == "s") s.type = SignalType::kSigned;
        else if (tok[5] == "f") s.type = SignalType::kFloat;
        else {
            what = "a signal's type is u, s or f (IEEE float), got '" + tok[5] + "'";
            return false;
        }
        if (s.type == SignalType::kFloat && s.length != 32 && s.length != 64) {
            what = "an IEEE float signal is 32 or 64 bits, got " + tok[3];
            return false;
        }
        if (!to_number(tok[6], s.scale) || !to_number(tok[7], s.offset)) return bad(raw, "signal");
        if (s.scale == 0) {
            what = "a signal's scale must not be 0";
            return false;
        }
        uint64_t mask = 0;
        int end_byte = 0;
        const int bytes = f.long_dlc ? f.long_dlc : f.dlc;
        if (!signal_bits(s.start, s.length, s.big_endian, mask, end_byte) || end_byte > bytes) {
            what = "the signal at bit " + tok[2] + " (" + tok[3] + " bits, " + tok[4] + ") leaves frame '" + f.name +
                   "''s " + std::to_string(bytes) + " bytes";
            return false;
        }
        if (mask & used_bits[size_t(fi)]) {
            what = "the signal at bit " + tok[2] + " overlaps another signal of frame '" + f.name + "'";
            return false;
        }
        used_bits[size_t(fi)] |= mask;
        if (!target(tok[8], s, fi, line)) return false;
        FrameDecoder::place(s);
        signals[size_t(fi)].push_back(s);
        signal_lines.push_back(line);
        return true;
    }

    bool target(const std::string& t, SignalDef& s, int fi, int line) {
        s.name = t;
        const bool flag = t == "restart" || t == "seq" || t == "reserved" || t == "fault" || t == "saturated" ||
                          t.rfind("fault.", 0) == 0 || t.rfind("saturated.", 0) == 0 || t.rfind("skin.", 0) == 0;
        if (flag && (s.type == SignalType::kFloat || s.scale != 1 || s.offset != 0)) {
            what = "'" + t + "' is a flag or a count: an integer signal with scale 1 and offset 0";
            return false;
        }
        Target v = Target::kNone;
        if (t == "-") {
            s.target = Target::kNone;
        } else if (t == "restart" || t == "seq") {
            const uint8_t bit = t == "restart" ? 1 : 2;
            if (frame_flags[size_t(fi)] & bit) {
                what = "a second '" + t + "' signal in frame '" + out.bus.frames[size_t(fi)].name + "'";
                return false;
            }
            frame_flags[size_t(fi)] |= bit;
            s.target = t == "restart" ? Target::kRestart : Target::kSeq;
            if (t == "seq" && (s.length < 2 || s.length > 32)) {
                what = "a sequence counter is 2 to 32 bits, got " + std::to_string(s.length);
                return false;
            }
        } else if (t == "reserved") {
            s.target = Target::kReserved;
        } else if (t == "fault" || t == "saturated") {
            s.target = t == "fault" ? Target::kFault : Target::kSaturated;
        } else if (t.rfind("fault.", 0) == 0 || t.rfind("saturated.", 0) == 0) {
            const bool fault = t[0] == 'f';
            if (!value_target(t.substr(fault ? 6 : 10), v)) {
                what = "'" + t + "': a flag's own target is a value target (q.J, dq.J, pwm.M, current.M, tau.J, ft.S.C)";
                return false;
            }
            s.target = fault ? Target::kFault : Target::kSaturated;
        } else if (t.rfind("skin.", 0) == 0) {
            s.target = Target::kSkin;
            bool known = false;
            for (size_t k = 0; k < out.bus.patches.size(); ++k)
                if (out.bus.patches[k].name == t.substr(5)) s.slot = int(k), known = true;
            if (!known) {
                what = "'" + t + "' names a patch no 'patch' line defines";
                return false;
            }
        } else if (value_target(t, v)) {
            s.target = v;
            const auto seen = value_line.find(t);
            if (seen != value_line.end()) {
                what = "'" + t + "' is carried by another signal already (line " + std::to_string(seen->second) + ")";
                return false;
            }
            if (const std::string why = implausible_signal(t, s); !why.empty()) return what = why, false;
            value_line[t] = line;
            s.slot = int(out.bus.values.size());
            out.bus.values.push_back(t);
        } else {
            what = "'" + t + "' is no signal target: q.J dq.J pwm.M current.M tau.J ft.S.C skin.P saturated[.T] "
                   "fault[.T] restart seq reserved, or - (read by nobody)";
            return false;
        }
        return true;
    }

    bool pair(const std::vector<std::string>& tok, const std::string& raw) {
        if (tok.size() != 3) return bad(raw, "pair");
        const int a = frame_index(tok[1]), b = a < 0 ? -1 : frame_index(tok[2]);
        if (a < 0 || b < 0) return false;
        if (a == b) {
            what = "frame '" + tok[1] + "' is paired with itself";
            return false;
        }
        for (int x : {a, b})
            if (out.bus.frames[size_t(x)].pair >= 0) {
                what = "frame '" + out.bus.frames[size_t(x)].name + "' is in another pair already";
                return false;
            }
        const int p = int(out.bus.pairs.size());
        out.bus.pairs.emplace_back(a, b);
        out.bus.frames[size_t(a)].pair = out.bus.frames[size_t(b)].pair = p;
        out.bus.frames[size_t(a)].first_half = true;
        return true;
    }

    // Every line but buses, frame and patch.
    bool line(const std::vector<std::string>& tok, const std::string& raw, int ln) {
        const std::string& key = tok[0];
        const size_t n = tok.size();
        auto setting = [&](double lo, double hi, const char* unit, double& v) {
            if (n != 2 || !to_number(tok[1], v)) return bad(raw, key);
            if (v < lo || v > hi) {
                what = key + " " + tok[1] + " is out of range: " + str(lo) + " to " + str(hi) + unit;
                return false;
            }
            return true;
        };
        auto integer_setting = [&](long long lo, long long hi, const char* unit, long long& v) {
            if (n != 2) return bad(raw, key);
            if (!to_integer(tok[1], v)) {  // 1e3, or a whole number beyond long long: its range is the problem
                double d = 0;
                if (!to_number(tok[1], d)) return bad(raw, key);
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
        static const char* kOnce[] = {"robot", "lcm_url", "stale_ms", "pair_us", "status_hz", "residual_every", "clock",
                                      "contact_limit_s"};
        for (const char* k : kOnce)
            if (key == k && !first_time(key, ln)) return false;
        if (key == "robot") {
            if (n != 2) return bad(raw, key);
            out.robot = tok[1];
        } else if (key == "lcm_url") {
            if (n != 2) return bad(raw, key);
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
        } else if (key == "contact_limit_s") {
            if (!setting(kContactLimitSMin, kContactLimitSMax, " s", out.contact_limit_s)) return false;
        } else if (key == "signal") {
            return signal(tok, raw, ln);
        } else if (key == "clock") {
            if (n != 2) return bad(raw, key);
            out.bus.clock = frame_index(tok[1]);
            return out.bus.clock >= 0;
        } else if (key == "pair") {
            return pair(tok, raw);
        } else if (key == "strain" || key == "axis" || key == "pwm" || key == "skin") {
            what = "'" + key + "' is a line of the iCub-only format before the bus description: write the "
                   "configuration again (dynid export --robot ROBOT --monitor-config FILE)";
            return false;
        } else {
            what = "unknown key '" + key + "'";
            return false;
        }
        return true;
    }

    // After every line: signals grouped by frame, frame kinds, and the rules that span lines.
    bool finish(std::string& error) {
        if (!once.count("robot"))
            return fail(error, path, 0, "no 'robot' line (the coefficient file's robot is checked against it)");
        if (out.bus.frames.empty()) return fail(error, path, 0, "no 'frame' line: the bus has no frames");
        if (!once.count("clock")) return fail(error, path, 0, "no 'clock' line (the frame that completes a sample)");
        BusTable& b = out.bus;
        const FrameDef& clock = b.frames[size_t(b.clock)];
        if (clock.first_half)
            return fail(error, path, once["clock"], "the clock frame '" + clock.name + "' is the first half of a "
                        "pair: the second half completes a sample");
        b.clock_pair = clock.pair;
        for (size_t i = 0; i < b.frames.size(); ++i) {
            FrameDef& f = b.frames[i];
            if (signals[i].empty())
                return fail(error, path, frame_line[i], "frame '" + f.name + "' has no 'signal' line");
            f.first_signal = int(b.signals.size());
            f.n_signals = int(signals[i].size());
            bool status = false, skin = false, position = false, ft = false;
            for (const SignalDef& s : signals[i]) {
                status |= s.target == Target::kSeq || s.target == Target::kRestart || s.target == Target::kFault;
                skin |= s.target == Target::kSkin;
                position |= s.target == Target::kQ || s.target == Target::kDq;
                ft |= s.target == Target::kFt;
                b.signals.push_back(s);
            }
            f.kind = (f.pair >= 0 && f.pair == b.clock_pair) || int(i) == b.clock ? FrameKind::kClock
                     : status ? FrameKind::kStatus : skin ? FrameKind::kSkin : position ? FrameKind::kPosition
                     : ft || f.pair >= 0 ? FrameKind::kSensor : FrameKind::kInput;
        }
        for (const SignalDef& s : b.signals) {  // a flag of a target: the target is on the bus
            const size_t dot = s.name.find('.');
            if ((s.target == Target::kFault || s.target == Target::kSaturated) && dot != std::string::npos &&
                !value_line.count(s.name.substr(dot + 1)))
                return fail(error, path, 0, "'" + s.name + "': no signal carries '" + s.name.substr(dot + 1) + "'");
        }
        for (size_t k = 0; k < b.patches.size(); ++k) {
            bool carried = false;
            for (const SignalDef& s : b.signals) carried |= s.target == Target::kSkin && s.slot == int(k);
            if (!carried)
                return fail(error, path, patch_line[k], "patch '" + b.patches[k].name + "' is carried by no signal "
                            "(target skin." + b.patches[k].name + ")");
        }
        return true;
    }
};

std::vector<std::string> tokens(const std::string& line) {
    std::istringstream s(line.substr(0, line.find('#')));
    std::vector<std::string> tok;
    for (std::string t; s >> t;) tok.push_back(t);
    return tok;
}

}  // namespace

bool parse_monitor_config(const std::string& text, const std::string& path, MonitorConfig& out, std::string& error) {
    out = MonitorConfig{};
    std::vector<std::string> lines;
    {
        std::istringstream in(text);
        for (std::string raw; std::getline(in, raw);) lines.push_back(raw);
    }
    // Keys come in any order: 'buses' first, then the 'patch' and 'frame' lines the others name, then every other
    // line in file order (repeated keys keep theirs: a frame's signals, the patches' bits in the skin mask).
    int buses_line = 0;
    for (size_t i = 0; i < lines.size(); ++i) {
        const std::vector<std::string> tok = tokens(lines[i]);
        if (tok.empty() || tok[0] != "buses") continue;
        const int ln = int(i) + 1;
        if (buses_line)
            return fail(error, path, ln, "a second 'buses' line (the first is line " + std::to_string(buses_line) + ")");
        for (size_t k = 1; k < tok.size(); ++k) {
            if (index_of(out.buses, tok[k]) >= 0) return fail(error, path, ln, "bus '" + tok[k] + "' named twice");
            out.buses.push_back(tok[k]);
        }
        if (out.buses.empty() || out.buses.size() > size_t(kMaxBuses))
            return fail(error, path, ln, "bad 'buses' line (1 to " + std::to_string(kMaxBuses) + " bus names): " + lines[i]);
        buses_line = ln;
    }
    if (!buses_line)
        return fail(error, path, 0, "no 'buses' line (not an rt_monitor configuration? `dynid export --robot CFG "
                                    "--monitor-config FILE` writes one)");
    Parser p(path, out);
    for (const char* pass : {"patch", "frame", ""}) {
        for (size_t i = 0; i < lines.size(); ++i) {
            const std::vector<std::string> tok = tokens(lines[i]);
            if (tok.empty() || tok[0] == "buses") continue;
            const bool mine = *pass ? tok[0] == pass : tok[0] != "patch" && tok[0] != "frame";
            if (!mine) continue;
            const int ln = int(i) + 1;
            const bool ok = tok[0] == "patch" ? p.patch(tok, lines[i], ln)
                            : tok[0] == "frame" ? p.frame(tok, lines[i], ln) : p.line(tok, lines[i], ln);
            if (!ok) return fail(error, path, ln, p.what);
        }
    }
    return p.finish(error);
}

bool load_monitor_config(const std::string& path, MonitorConfig& out, std::string& error) {
    // stdio, so that a read error is one (a directory read as an ifstream was an empty file: "no 'buses' line").
    constexpr size_t kMaxBytes = size_t(1) << 20;  // a configuration is tens of kB; /dev/zero is not one
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

std::vector<uint32_t> bus_ids(const MonitorConfig& c, int bus) {
    std::vector<uint32_t> out;
    for (const FrameDef& f : c.bus.frames) if (f.bus == bus) out.push_back(f.id);
    return out;
}

}  // namespace dynid::rt
