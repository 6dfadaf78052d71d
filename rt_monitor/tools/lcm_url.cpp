// The monitor's LCM URL (lcm_url.hpp).
#include "lcm_url.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <iterator>

namespace dynid::rt {

// LCM opens a file:// URL for reading unless its query says mode=w or mode=a (the last mode= wins, as in liblcm);
// the monitor only publishes, so such a URL can only fail (or, on an existing log, be read from). Returns the URL it
// should have been, or "" if fine. dynid.export.monitor_config.url_for_writing is the same rule (tested together).
std::string file_url_for_writing(const std::string& url) {
    if (url.rfind("file://", 0) != 0) return "";
    const size_t query = url.find('?');
    if (query == std::string::npos) return url + "?mode=w";
    size_t value = std::string::npos, end = std::string::npos;  // the last mode='s value [value, end)
    for (size_t at = query; at != std::string::npos; at = url.find('&', at + 1))
        if (url.compare(at + 1, 5, "mode=") == 0) value = at + 6, end = std::min(url.find('&', at + 1), url.size());
    if (value == std::string::npos) return url + (query + 1 == url.size() ? "" : "&") + "mode=w";
    const std::string mode = url.substr(value, end - value);
    return mode == "w" || mode == "a" ? "" : url.substr(0, value) + "w" + url.substr(end);
}

// Why liblcm could not open `url` as the monitor's LCM, or "" (an empty URL: LCM's default): a provider liblcm lacks,
// a UDP multicast group outside 224.0.0.0/4, a port or ttl out of range. A configuration error (exit 2), found before
// anything is opened; dynid.export.monitor_config.lcm_url_problem is the same rule (tested together).
std::string lcm_url_problem(const std::string& url) {
    if (url.empty()) return "";
    const size_t sep = url.find("://");
    const std::string provider = sep == std::string::npos ? url : url.substr(0, sep);
    static const char* kProviders[] = {"udpm", "mpudpm", "file", "memq", "tcpq"};
    if (sep == std::string::npos ||
        std::none_of(std::begin(kProviders), std::end(kProviders), [&](const char* p) { return provider == p; }))
        return "no LCM provider '" + provider + "' (liblcm has udpm, mpudpm, file, memq, tcpq: PROVIDER://...)";
    const std::string rest = url.substr(sep + 3);
    const size_t q = rest.find('?');
    const std::string network = rest.substr(0, q), query = q == std::string::npos ? "" : rest.substr(q + 1);
    if (provider == "file" && network.empty()) return "a file:// URL names its log: file:///PATH?mode=w";
    if (provider != "udpm" && provider != "mpudpm") return "";
    const auto digits = [](const std::string& v) {
        return !v.empty() && v.size() <= 5 && std::all_of(v.begin(), v.end(), [](char c) { return c >= '0' && c <= '9'; });
    };
    if (!network.empty()) {
        const size_t colon = network.find(':');
        const std::string address = network.substr(0, colon);
        int part[4], n = 0;
        bool ok = true;
        for (size_t at = 0; ok && n < 5; ++n) {
            const size_t dot = address.find('.', at);
            const std::string v = address.substr(at, dot == std::string::npos ? std::string::npos : dot - at);
            ok = digits(v) && std::stoi(v) <= 255 && n < 4;
            if (ok) part[n] = std::stoi(v);
            if (dot == std::string::npos) { ++n; break; }
            at = dot + 1;
        }
        if (!ok || n != 4 || part[0] < 224 || part[0] > 239)
            return "'" + address + "' is not a UDP multicast group (224.0.0.0-239.255.255.255)";
        if (colon != std::string::npos) {
            const std::string port = network.substr(colon + 1);
            if (!digits(port) || std::stoi(port) < 1 || std::stoi(port) > 65535) return "port '" + port + "' is not 1-65535";
        }
    }
    for (size_t at = 0; at <= query.size() && !query.empty();) {
        const size_t amp = query.find('&', at);
        const std::string pair = query.substr(at, amp == std::string::npos ? std::string::npos : amp - at);
        if (pair.rfind("ttl=", 0) == 0 || pair == "ttl") {
            const std::string v = pair.size() > 4 ? pair.substr(4) : "";
            if (!digits(v) || std::stoi(v) > 255) return "ttl '" + v + "' is not 0-255";
        }
        if (amp == std::string::npos) break;
        at = amp + 1;
    }
    return "";
}

// lcm::LCM(url), with what liblcm writes to fd 2 meanwhile returned in `said` (whitespace folded to one line).
std::unique_ptr<lcm::LCM> open_lcm(const std::string& url, std::string& said) {
    std::fflush(stderr);
    std::FILE* tmp = std::tmpfile();
    const int saved = tmp ? dup(2) : -1;
    if (saved >= 0) dup2(fileno(tmp), 2);
    auto lc = std::make_unique<lcm::LCM>(url);
    if (saved >= 0) {
        std::fflush(stderr);
        dup2(saved, 2);
        close(saved);
        std::rewind(tmp);
        int ch = 0;
        bool space = false;
        while ((ch = std::fgetc(tmp)) != EOF) {
            if (ch == '\n' || ch == '\r' || ch == '\t' || ch == ' ') {
                space = !said.empty();
                continue;
            }
            if (space) said += ' ';
            space = false;
            said += char(ch);
        }
    }
    if (tmp) std::fclose(tmp);
    return lc;
}

// A failed or stopped replay leaves the log it would have replaced as it was; its own log, whose status messages say
// what went wrong, becomes PATH.failed (a live run's log is a recording, written in place). Where liblcm would refuse
// the path (a missing folder, a directory), the URL is left for it to refuse.
bool partial_log(std::string& url, PartialLog& log) {
    if (url.rfind("file://", 0) != 0) return false;
    const size_t query = url.find('?');
    const std::string path = url.substr(7, query == std::string::npos ? std::string::npos : query - 7);
    const std::string options = query == std::string::npos ? "" : url.substr(query);
    // liblcm takes the last mode=: appending replaces nothing
    const size_t mode = options.rfind("mode=");
    if (path.empty() || (mode != std::string::npos && options.compare(mode, 6, "mode=a") == 0)) return false;
    struct stat st {};
    if (lstat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) return false;  // a link is written through, as liblcm does
    const size_t slash = path.rfind('/');
    const std::string folder = slash == std::string::npos ? "." : slash == 0 ? "/" : path.substr(0, slash);
    if (stat(folder.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) return false;
    log = {path, path + ".partial"};
    url = "file://" + log.partial + options;
    return true;
}

}  // namespace dynid::rt
