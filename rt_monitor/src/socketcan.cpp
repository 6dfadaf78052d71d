// SocketCAN raw sockets (production source). Filters and the datagram reader are shared with the loopback
// transport and tested on every machine; only socket()/bind() need a kernel with AF_CAN.
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "rt_monitor/frame_source.hpp"

namespace dynid::rt {

std::vector<can_filter> socketcan_filters(const std::vector<uint32_t>& ids) {
    std::vector<can_filter> out;
    for (uint32_t id : ids) {
        can_filter f{};
        f.can_id = id & CAN_SFF_MASK;
        // Every ID bit, and EFF/RTR clear: this standard-ID data frame only.
        f.can_mask = CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG;
        out.push_back(f);
    }
    return out;
}

bool socketcan_filter_passes(const std::vector<can_filter>& filters, canid_t id) noexcept {
    for (const can_filter& f : filters)
        if ((id & f.can_mask) == (f.can_id & f.can_mask)) return true;
    return false;
}

std::unique_ptr<SocketCanSource> SocketCanSource::open(const std::vector<std::string>& interfaces,
                                                       const std::vector<std::vector<can_filter>>& filters,
                                                       std::string& error) {
    std::unique_ptr<SocketCanSource> s(new SocketCanSource());
    if (filters.size() != interfaces.size()) {
        error = "one filter list per interface is needed";
        return nullptr;
    }
    for (size_t i = 0; i < interfaces.size(); ++i) {
        const std::string& name = interfaces[i];
        const std::vector<can_filter>& mine = filters[i];
        const int fd = socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
        if (fd < 0) {
            const int e = errno;
            error = name + ": socket(AF_CAN, SOCK_RAW, CAN_RAW): " + std::strerror(e) +
                    (e == EAFNOSUPPORT ? " (this kernel has no SocketCAN: modprobe can_raw, or use --replay)" : "");
            return nullptr;
        }
        s->fds_.push_back(fd);
        const can_err_mask_t errs = CAN_ERR_MASK;  // every error class: each is counted
        const int on = 1;
        if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, mine.data(), socklen_t(mine.size() * sizeof(can_filter))) != 0 ||
            setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &errs, sizeof errs) != 0 ||
            setsockopt(fd, SOL_SOCKET, SO_TIMESTAMP, &on, sizeof on) != 0 ||
            setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) != 0) {  // frames dropped by the kernel, counted
            error = name + ": setsockopt (CAN filters, timestamps, drop count): " + std::strerror(errno);
            return nullptr;
        }
        const unsigned index = if_nametoindex(name.c_str());
        if (index == 0) {
            error = name + ": no such CAN interface (ip link add dev " + name + " type vcan, or bring it up)";
            return nullptr;
        }
        sockaddr_can a{};
        a.can_family = AF_CAN;
        a.can_ifindex = int(index);
        if (bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
            error = name + ": bind: " + std::strerror(errno);
            return nullptr;
        }
    }
    return s;
}

SocketCanSource::~SocketCanSource() {
    for (int fd : fds_) ::close(fd);
}

ReadStatus SocketCanSource::read(RxFrame& out, int timeout_ms) noexcept {
    return read_datagram(fds_, queue_, timeout_ms, out, counters_, error_);
}

}  // namespace dynid::rt
