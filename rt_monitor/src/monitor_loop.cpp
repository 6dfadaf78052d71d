// rt_monitor's loop (monitor_loop.hpp).
#include "rt_monitor/monitor_loop.hpp"

#include <ctime>

namespace dynid::rt {

double mono_us() noexcept {
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return double(ts.tv_sec) * 1e6 + double(ts.tv_nsec) * 1e-3;
}

double real_us() noexcept {
    timespec ts{};
    clock_gettime(CLOCK_REALTIME, &ts);
    return double(ts.tv_sec) * 1e6 + double(ts.tv_nsec) * 1e-3;
}

MonitorLoop::MonitorLoop(const MonitorConfig& cfg, const Coefficients& coef, Core& core, Assembler& assembler,
                         Publisher& publisher, Watchdog& watchdog, const LoopOptions& options)
    : cfg_(cfg), core_(core), asm_(assembler), pub_(publisher), dog_(watchdog), opt_(options),
      clock_(coef.sample_period * 1e6), coverage_(coef), period_us_(coef.sample_period * 1e6) {
    if (opt_.stats) {
        processing_.init(period_us_);
        response_.init(period_us_);
    }
    latency_.reserve(opt_.latency_capacity);  // allocated once: no allocation in the loop
}

void MonitorLoop::step(const Sample& x) noexcept {
    const double t0 = mono_us();
    const Output& o = core_.step(x.q.data(), x.has_dq ? x.dq.data() : nullptr, x.y.data());
    const double dt = mono_us() - t0;
    loop_sum_ += dt;
    loop_max_ = dt > loop_max_ ? dt : loop_max_;
    n_.loop_max_us = dt > n_.loop_max_us ? dt : n_.loop_max_us;
    ++loop_n_;
    if (dt > period_us_) ++n_.overruns;
    ++n_.evaluated;
    dog_.evaluated(o, x.t_us);
    const uint64_t beyond = coverage_.check(x.q.data());
    n_.beyond_fit = coverage_.samples();
    if (o.peak_now) peak_utime_ = x.t_us, peak_beyond_ = beyond;
    last_evaluated_utime_ = x.t_us;
    if (o.event != Event::kNone) {
        ++n_.events;
        ++(o.event == Event::kOnset ? n_.onsets : n_.ends);
        if (o.event == Event::kOnset) onset_utime_ = x.t_us;
        pub_.contact(o, x.t_us, onset_utime_, peak_utime_, n_.evaluated - 1, peak_beyond_, dog_.active());
        n_.events_under_fault += dog_.active() != 0;
        if (o.event == Event::kOnset && latency_.size() < latency_.capacity()) latency_.push_back(mono_us() - rx_mono_);
    }
    if (o.ready && n_.evaluated % cfg_.residual_every == 0) pub_.residual(o, x.t_us);
}

void MonitorLoop::place(const ClockStep& c) noexcept {
    dog_.placed(c.interpolated, c.restart);
    if (c.restart) {
        // A filter restart resets the detector: a contact open then is cut, said by an event of its own (kind 3, at
        // its last evaluated sample, with its peak), so that a consumer following the events never holds a contact
        // open that the monitor no longer tracks (a review: a saturation in contact left it open for good)
        if (core_.output().in_contact) {
            ++n_.cut;
            ++n_.events;
            pub_.contact(core_.output(), last_evaluated_utime_, onset_utime_, peak_utime_, n_.evaluated - 1,
                         peak_beyond_, dog_.active(), kCutEvent);
            n_.events_under_fault += dog_.active() != 0;
        }
        core_.reset();
    }
    step(c.sample);
}

void MonitorLoop::fill_status(int64_t t_us) noexcept {
    const MonitorCounters& c = asm_.counters();
    const SourceCounters& sc = src_->counters();
    dynid::monitor_status_t& st = pub_.status();
    st.frames = c.frames;
    st.samples = c.samples;
    st.samples_evaluated = n_.evaluated;
    st.stale_samples = c.stale_samples;
    st.unknown_id = c.unknown_id;
    st.bad_length = c.bad_length;
    st.error_frames = c.error_frames;
    st.unpaired_strain = c.unpaired_strain;
    st.saturated = c.saturated;
    st.board_faults = c.board_faults;
    st.board_restarts = c.board_restarts;
    st.source_bad = int64_t(sc.bad_lines + sc.unknown_bus + sc.bad_size);
    st.interpolated = clock_.counters().interpolated;
    st.late = clock_.counters().late;
    st.filter_restarts = clock_.counters().restarts;
    st.in_contact = core_.output().in_contact;
    st.stale = sample_.stale;
    st.loop_us_mean = loop_n_ ? loop_sum_ / double(loop_n_) : 0.0;
    st.loop_us_max = loop_max_;
    st.overruns = n_.overruns;
    st.beyond_fit = coverage_.samples();
    st.beyond_fit_joints = int64_t(coverage_.last());
    st.faults = int32_t(dog_.active());
    st.faults_seen = int32_t(dog_.seen());
    pub_.publish_status(t_us);
    loop_sum_ = loop_max_ = 0;
    loop_n_ = 0;
}

int MonitorLoop::run(FrameSource& source, const volatile std::sig_atomic_t& stop) {
    src_ = &source;
    const int64_t status_period = status_period_us(cfg_);
    int64_t next_status = -1, last_frame_t = -1;
    double last_frame_wall = mono_us(), last_idle_status = 0;
    uint32_t faults_published = 0;
    int rc = 0;
    RxFrame f;
    // The wall clock at each frame's arrival: what a live source's silence, the latency and the response times are
    // measured from. An unpaced replay without them reads it only at the frames that complete a sample (one clock
    // read a frame was a tenth of its time).
    const bool every_frame = opt_.live || opt_.stats || opt_.latency_capacity > 0;
    const long long allocations_at_start = allocations();  // start-up is over: from here on, the loop
    while (!stop) {
        const ReadStatus r = src_->read(f, 100);
        if (r == ReadStatus::kEnd) break;
        if (r == ReadStatus::kTimeout) {
            // Nothing for a while: a live source whose boards went silent is a fault, and the status says so at its
            // rate in wall time, since CAN time no longer advances.
            const double now = mono_us();
            dog_.idle(int64_t(now - last_frame_wall));
            if (last_frame_t >= 0 && (now - last_idle_status >= double(status_period) || dog_.active() != faults_published)) {
                fill_status(last_frame_t + int64_t(now - last_frame_wall));
                faults_published = dog_.active();
                last_idle_status = now;
            }
            continue;
        }
        if (every_frame) rx_mono_ = mono_us(), last_frame_wall = rx_mono_;
        dog_.idle(0);
        if (r == ReadStatus::kError) {
            std::fprintf(stderr, "rt_monitor: error: %s\n", src_->error().c_str());
            rc = 1;
            break;
        }
        const int64_t previous_t = last_frame_t;
        last_frame_t = f.t_us;
        const uint32_t before = dog_.active();  // a fault this frame raises or clears, in any of the calls below
        dog_.frame(f.t_us);
        const bool completed = asm_.push(f, sample_);
        if (completed) {
            if (!every_frame) rx_mono_ = mono_us(), last_frame_wall = rx_mono_;
            dog_.sample(sample_);
            // The sample clock decides which tick each sample is (jitter or loss, from the stamps), bridges real gaps
            // and says when the filter restarts; stale samples are not evaluated (no contact from stale data).
            for (int i = 0, n = clock_.push(sample_); i < n; ++i) place(clock_.step(i));
        }
        dog_.check(f.t_us);
        // Stamps that went back a status period or more (a sender's clock reset, an NTP step of a live source's
        // receive time): the status is due at once, its period counted from there, or it would wait for CAN time to
        // catch up with the old stamps
        if (previous_t >= 0 && f.t_us + status_period < previous_t) next_status = f.t_us;
        const bool due = next_status >= 0 && f.t_us >= next_status;
        if (next_status < 0) next_status = f.t_us;
        if (due || dog_.active() != before) {  // on the status period, and at once when a fault rises or clears
            fill_status(f.t_us);
            faults_published = dog_.active();
            if (due) {
                dog_.check_bus(f.t_us);
                next_status += status_period;
                if (next_status <= f.t_us) next_status = f.t_us + status_period;
            }
        }
        if (completed) {
            const double done = mono_us();
            processing_.add(done - rx_mono_, sample_.t_us);
            response_.add(opt_.live ? real_us() - double(f.t_us) : done - rx_mono_, sample_.t_us);
        }
    }
    for (int i = 0, n = clock_.flush(); i < n; ++i) place(clock_.step(i));
    if (last_frame_t >= 0) {
        dog_.check(last_frame_t);
        fill_status(last_frame_t);
    }
    n_.allocations = allocations() - allocations_at_start;
    return rc;
}

}  // namespace dynid::rt
