"""`dynid spy`: a live terminal view of rt_monitor's LCM output (contact events, the latest status, rates).

Decodes with the generated Python types (dynid.export.lcm_messages, lcm-gen's output for rt_monitor/lcmtypes). Rates are
per second of the monitor's CAN time (the status messages' utime), so a log replayed faster than real time shows
the rates the boards had. `--json` prints one JSON object per message instead (NDJSON: {"channel": ..., "message": {field: value}}), then
{"summary": ...}.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import struct
import sys
import tempfile
import time
from collections.abc import Iterator
from typing import Any, Callable

from ..errors import InputError
from ..export.monitor_config import url_for_writing
from ..export.monitor_log import ratios_text
from .commands import COMMANDS
from .common import plural, positive_float, positive_int

CHANNELS = ("DYNID_CONTACT", "DYNID_STATUS", "DYNID_RESIDUAL")
KIND = {1: "onset", 2: "end", 3: "cut"}  # cut: the filter restarted in contact, its end unknown
SIDE = {1: "distal", -1: "proximal", 0: "unknown side"}
# Status counters that mean trouble, or timing artefacts (interpolated, late): shown (and named in the summary)
# when not zero.
PROBLEMS = ("stale_samples", "unknown_id", "bad_length", "error_frames", "unpaired_strain", "saturated",
            "board_faults", "board_restarts", "source_bad", "interpolated", "late", "filter_restarts", "overruns")
# The watchdog's fault bits (rt_monitor/include/rt_monitor/watchdog.hpp, the status message's `faults`)
FAULTS = ("BLIND", "FRAME SILENT", "T² NOT FINITE", "SAMPLE PERIOD", "JOINT OUT OF RANGE", "SOURCE STOPPED",
          "DUTY OUT OF RANGE", "MODEL DOES NOT FIT AT START", "SAMPLES BRIDGED", "STAMPS WENT BACK", "CONTACT TOO LONG")


def fault_text(bits: int) -> str:
    return ", ".join(name for k, name in enumerate(FAULTS) if bits >> k & 1)


def supply_text(ratios: Any) -> str:
    """'supply r 1.0123 0.9871 …' ('' if none): the status line's field."""
    return "supply r " + ratios_text(ratios) if len(ratios) else ""


def open_lcm(url: str | None) -> Any:
    """lcm.LCM(url), or an InputError with liblcm's own complaint (it writes it to fd 2) on the same line."""
    import lcm

    with tempfile.TemporaryFile() as err:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(err.fileno(), 2)
        try:
            return lcm.LCM(url) if url else lcm.LCM()
        except RuntimeError:
            os.dup2(saved, 2)
            err.seek(0)
            why = err.read().decode(errors="replace").strip() or "liblcm refused it"
            raise InputError(f"cannot open LCM at '{url or 'the default URL'}': {why}") from None
        finally:
            os.dup2(saved, 2)
            os.close(saved)


@contextlib.contextmanager
def liblcm_stderr(capture: bool) -> Iterator[dict[str, Any]]:
    """While reading a file:// log, what liblcm writes to fd 2 (e.g. "Invalid header after log data" at a damaged
    spot) is kept, to go on the summary's line instead of a line of its own; `warn` writes to the real stderr."""
    if not capture:
        yield {"warn": lambda text: sys.stderr.write(text), "text": ""}
        return
    with tempfile.TemporaryFile() as err:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(err.fileno(), 2)
        out: dict[str, Any] = {"warn": lambda text: os.write(saved, text.encode()), "text": ""}
        try:
            yield out
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            err.seek(0)
            out["text"] = " ".join(err.read().decode(errors="replace").split())


def plain(v: Any) -> Any:
    """A decoded LCM field as JSON has it: arrays (of any depth, e.g. each sensor's wrench) as lists."""
    return [plain(x) for x in v] if isinstance(v, (list, tuple)) else v


def message_dict(msg: Any) -> dict[str, Any]:
    return {k: plain(getattr(msg, k)) for k in msg.__slots__}


class View:
    """The human view: one line per contact event; the status line redrawn in place on a terminal, or printed once a
    second of CAN time otherwise."""

    def __init__(self, out: Any, tty: bool) -> None:
        self.out, self.tty = out, tty
        self.t0: int | None = None
        self.prev: Any = None
        self.printed_at = -(10**18)
        self.status_line = ""

    def _t(self, utime: int) -> float:
        if self.t0 is None:
            self.t0 = utime
        return (utime - self.t0) * 1e-6

    def _write(self, line: str) -> None:
        if self.tty:  # clear the status line, write, redraw it below
            self.out.write("\r\x1b[K" + line + "\n" + self.status_line)
        else:
            self.out.write(line + "\n")
        self.out.flush()

    def event(self, m: Any) -> None:
        """An onset or end: T², then every sensor's side and residual wrench, the isolated link and the largest
        external joint torques (the event carries all of them: `--json` prints each field); an end's describe its
        contact's strongest sample, the peak it names."""
        line = f"{self._t(m.utime):10.3f} s  contact {KIND.get(m.kind, m.kind):5}  T² {m.t2:9.1f} (threshold {m.threshold:.1f})"
        if m.kind == 3:
            line += "  (the filter restarted in contact, a gap in the samples: its end unknown)"
        if m.kind in (2, 3):
            line += f"  peak T² {m.peak_t2:.1f} at {self._t(m.peak_utime):.3f} s:"
        for name, side, w in zip(m.sensor, m.side, m.wrench):
            line += (f"  {name}: {SIDE.get(side, side)} F [{w[0]:7.2f} {w[1]:7.2f} {w[2]:7.2f}] N "
                     f"τ [{w[3]:6.3f} {w[4]:6.3f} {w[5]:6.3f}] Nm")
        if m.isolated_joint >= 0:
            line += f"  on {m.isolated_link or m.joint[m.isolated_joint]} or beyond"
        largest = sorted(zip(m.joint, m.tau_ext), key=lambda jt: -abs(jt[1]))[:3]
        if largest and abs(largest[0][1]) > 0:
            line += "  τ_ext " + ", ".join(f"{j} {t:+.2f}" for j, t in largest) + " Nm"
        beyond = [j for j, b in zip(m.joint, m.beyond_fit) if b]
        if beyond:
            line += f"  BEYOND THE FIT'S POSTURES ({', '.join(beyond)}: α untested there)"
        if getattr(m, "faults", 0):  # a log of a monitor before the field: none
            line += f"  UNDER FAULT: {fault_text(m.faults)} (from data the monitor suspects)"
        self._write(line)

    def status(self, m: Any) -> None:
        t = self._t(m.utime)
        rate = ""
        if self.prev is not None and m.utime > self.prev.utime:
            dt = (m.utime - self.prev.utime) * 1e-6
            rate = (f"  {(m.frames - self.prev.frames) / dt:7.0f} frames/s  "
                    f"{(m.samples_evaluated - self.prev.samples_evaluated) / dt:5.0f} samples/s")
        self.prev = m
        problems = "  ".join(f"{k.replace('_', ' ')} {getattr(m, k)}" for k in PROBLEMS if getattr(m, k))
        faults = getattr(m, "faults", 0)
        self.status_line = (f"{t:10.3f} s  {'IN CONTACT' if m.in_contact else 'no contact'}"
                            + (f"  FAULT: {fault_text(faults)}" if faults else "")
                            + f"{'  STALE' if m.stale else ''}  frames {m.frames}  samples {m.samples} assembled, "
                            f"{m.samples_evaluated} evaluated{rate}  loop {m.loop_us_mean:.1f}/{m.loop_us_max:.1f} µs"
                            + (f"  {supply_text(m.supply_ratio)}" if m.n_supply else "")
                            + (f"  beyond the fit's postures {m.beyond_fit}" if m.beyond_fit else "")
                            + (f"  {problems}" if problems else ""))
        if self.tty:
            self.out.write("\r\x1b[K" + self.status_line)
            self.out.flush()
        elif m.utime - self.printed_at >= 1_000_000:
            self.printed_at = m.utime
            self._write(self.status_line)

    def close(self) -> None:
        if self.tty and self.status_line:
            self.out.write("\n")


def spy(lc: Any, count: int | None, duration: float | None, on_message: Callable[[str, Any], None],
        end_of_log_ok: bool, skipped: list[int], warn: Callable[[str], Any] = sys.stderr.write) -> str:
    """Handle messages until `count` contact events, `duration` seconds, the end of a file:// log, or Ctrl-C;
    `skipped[0]` counts the messages that do not decode (the first is said through `warn`)."""
    from ..export.lcm_messages import contact_event_t, monitor_status_t, residual_t

    types = {"DYNID_CONTACT": contact_event_t, "DYNID_STATUS": monitor_status_t, "DYNID_RESIDUAL": residual_t}
    events = 0

    def handler(channel: str, data: bytes) -> None:
        nonlocal events
        try:
            msg = types[channel].decode(data)
        except (ValueError, struct.error):
            # Another type on our channel name (a fingerprint mismatch), or a damaged message of ours (its arrays
            # shorter than their counts: a struct.error traceback before). Said once, then counted: a log full of
            # them printed a line each.
            skipped[0] += 1
            if skipped[0] == 1:
                warn(f"dynid spy: {channel}: a message that is not a {types[channel].__name__}, skipped (any further "
                     "ones are counted in the summary)\n")
            return
        events += channel == "DYNID_CONTACT"
        on_message(channel, msg)

    for ch in CHANNELS:
        lc.subscribe(ch, handler)
    deadline = None if duration is None else time.monotonic() + duration
    try:
        while True:
            if count is not None and events >= count:
                return f"{count} contact event{'s' * (count != 1)}"
            wait = 200 if deadline is None else int(min(200, max(0.0, deadline - time.monotonic()) * 1000))
            if deadline is not None and wait <= 0:
                return f"{duration:g} s"
            try:
                lc.handle_timeout(wait)
            except OSError:
                if end_of_log_ok:
                    return "end of the log"
                raise InputError("LCM stopped delivering (liblcm returned an error)") from None
    except KeyboardInterrupt:
        return "interrupted"


def cmd_spy(args: argparse.Namespace) -> dict[str, Any]:
    if args.count is not None and args.duration is not None:
        raise InputError("--count and --duration exclude each other")
    url = args.lcm_url or ""
    if url.startswith("file://") and url_for_writing(url) is None:  # the last mode= is w or a: LCM opens it to write
        raise InputError(f"--lcm-url {url} opens its log for writing (mode=w empties it), and spy reads: give the "
                         f"file:// URL without mode=, e.g. {url.split('?', 1)[0]}?speed=0")
    lc = open_lcm(args.lcm_url)
    counts = {ch: 0 for ch in CHANNELS}
    onsets = ends = 0
    last: dict[str, Any] = {}
    view = None if args.json_lines else View(sys.stdout, sys.stdout.isatty())

    def on_message(channel: str, msg: Any) -> None:
        nonlocal onsets, ends
        counts[channel] += 1
        if channel == "DYNID_CONTACT":
            onsets += msg.kind == 1
            ends += msg.kind == 2
        if channel == "DYNID_STATUS":
            last["status"] = msg
        if view is None:
            sys.stdout.write(json.dumps({"channel": channel, "message": message_dict(msg)}) + "\n")
        elif channel == "DYNID_CONTACT":
            view.event(msg)
        elif channel == "DYNID_STATUS":
            view.status(msg)

    skipped = [0]
    log = url.startswith("file://")
    with liblcm_stderr(capture=log) as lib:
        why = spy(lc, args.count, args.duration, on_message, end_of_log_ok=log, skipped=skipped, warn=lib["warn"])
    if lib["text"]:
        why += f" (liblcm: {lib['text']})"
    status = message_dict(last["status"]) if "status" in last else None
    summary = {"stopped": why, "messages": counts, "onsets": onsets, "ends": ends, "last_status": status,
               "skipped": skipped[0]}
    if view is not None:
        view.close()
        problems = [f"{k.replace('_', ' ')} {status[k]}" for k in PROBLEMS if status and status[k]]
        print(f"dynid spy: stopped ({why}): {plural(counts['DYNID_CONTACT'], 'contact event')} "
              f"({plural(onsets, 'onset')}, {plural(ends, 'end')}), "
              f"{counts['DYNID_STATUS']} status, {counts['DYNID_RESIDUAL']} residual messages"
              + (f", {skipped[0]} that do not decode skipped" if skipped[0] else "")
              + (f"; last status: frames {status['frames']}, samples {status['samples']}, evaluated "
                 f"{status['samples_evaluated']}" + (", " + ", ".join(problems) if problems else ", no problems counted")
                 + (f", {supply_text(status['supply_ratio'])}" if status["n_supply"] else "")
                 + (f", {status['beyond_fit']} beyond the fit's postures (α untested there)"
                    if status["beyond_fit"] else "")
                 if status else "; no status message"))
    else:
        sys.stdout.write(json.dumps({"summary": summary}) + "\n")
    return summary


def add_commands(sub: argparse._SubParsersAction) -> None:
    sp = sub.add_parser("spy", help=COMMANDS["spy"].help,
        description="Subscribe to DYNID_CONTACT, DYNID_STATUS and DYNID_RESIDUAL and show each contact event and the "
        "latest status (counters, frame and sample rates per second of CAN time, loop time). Runs until --count "
        "contact events, --duration seconds, the end of a file:// log, or Ctrl-C.")
    sp.add_argument("--lcm-url", metavar="URL", help="LCM URL (default: LCM's, UDP multicast with ttl=0, or "
                    "$LCM_DEFAULT_URL); file://LOG?speed=0 reads a log as fast as possible")
    sp.add_argument("--count", type=positive_int, metavar="N", help="stop after N contact events")
    sp.add_argument("--duration", type=positive_float, metavar="S", help="stop after S seconds")
    sp.add_argument("--json", dest="json_lines", action="store_true",
                    help="one JSON object per message on stdout (NDJSON), then {\"summary\": ...}")
    sp.set_defaults(func=cmd_spy)
