#!/usr/bin/env python3
"""A decoder of the rollcal wire protocol written from docs/wire.md alone
(no Rust code): an independent check of the page's field tables.

    tools/wire_decode.py stream STREAM.bin [--samples OUT] [--csv CSV]
        decode a stream; print the frame counters and the messages by type;
        with --samples, write one line per Sample: its fields, every float
        as the hex of its IEEE 754 bits (exact); with --csv, compare every
        Sample with the rows of `host-sim record --format csv` (same
        scenario and seed; docs/csv.md), bit for bit, and exit 1 on a
        difference.
    tools/wire_decode.py doc docs/wire.md
        decode every worked example of the page (`frame (NAME): N bytes`),
        check that its `raw` block (if any) is the frame's COBS decoding,
        and print each message on one line.

`tests/it/wire_doc.rs` runs both and compares them with the Rust decoder.
"""

import re
import struct
import sys
import zlib

VERSION = 8


class Malformed(Exception):
    pass


def cobs_decode(data):
    """The COBS decoding of a frame without its delimiter, or None (truncated)."""
    out, i, n = bytearray(), 0, len(data)
    while i < n:
        code = data[i]
        i += 1
        if code == 0 or i + code - 1 > n:
            return None
        out += data[i:i + code - 1]
        i += code - 1
        if code != 0xFF and i < n:
            out.append(0)
    return bytes(out)


class Reader:
    def __init__(self, data):
        self.d, self.i = data, 0

    def take(self, n):
        if self.i + n > len(self.d):
            raise Malformed("payload ends inside a value")
        b = self.d[self.i:self.i + n]
        self.i += n
        return b

    def varint(self, max_bytes, last_max):
        out = 0
        for k in range(max_bytes):
            b = self.take(1)[0]
            out |= (b & 0x7F) << (7 * k)
            if not b & 0x80:
                if k == max_bytes - 1 and b > last_max:
                    raise Malformed("bad varint")
                return out
        raise Malformed("bad varint")

    def u8(self):
        return self.take(1)[0]

    def u32(self):
        return self.varint(5, 0x0F)

    def u64(self):
        return self.varint(10, 0x01)

    def f32(self):
        return self.take(4).hex()  # the bits, little-endian

    def f64(self):
        return self.take(8).hex()

    def bool(self):
        b = self.u8()
        if b > 1:
            raise Malformed("bad bool")
        return b == 1

    def option(self, read):
        tag = self.u8()
        if tag > 1:
            raise Malformed("bad option")
        return read() if tag == 1 else None

    def array(self, read, n):
        return [read() for _ in range(n)]

    def vec(self, read, cap):
        n = self.u32()
        if n > cap:
            raise Malformed("vector longer than its capacity")
        return [read() for _ in range(n)]

    def enum(self, n_variants):
        v = self.u32()
        if v >= n_variants:
            raise Malformed("unknown enum index")
        return v


MAX_STATES = 54
MAX_FACTOR = MAX_STATES * (MAX_STATES + 1) // 2
CONFIG_IDS = ["M1-pa", "M1-ps", "M2-ps", "M3-pa", "M3-ps", "M4-pa", "M4-ps"]
ERROR_MODELS = ["Installation", "Full"]
SINGLE_PASS = ["NoLog", "LogFull", "LogStorage", "LogMismatch", "Reacquired",
               "FilterFailed", "Estimator", "LogUnrepresentable"]
REJECTS = ["non_finite", "period", "accel_range", "increment_range", "gimbal_range",
           "missing_gimbal", "duplicate", "out_of_order", "time_backwards",
           "time_mismatch", "frame_attitude", "filter"]


def sample(r):
    return dict(seq=r.u32(), t_us=r.u64(), dt=r.f32(),
                dtheta_cmd=r.array(r.f64, 3), c_cn_quat=r.array(r.f32, 4),
                accel_mean=r.array(r.f32, 3),
                gimbal=r.option(lambda: r.array(r.f32, 3)))


def progress(r):
    p = dict(last_seq=r.option(r.u32), last_t_us=r.option(r.u64),
             last_increment=r.array(r.f64, 3),
             clock_candidate=r.option(lambda: (r.u32(), r.u64())),
             last_nis=r.f64())
    for name in ["accepted", "bridged", "reacquired", "reacquired_periods",
                 "clock_steps", "logged"]:
        p[name] = r.u32()
    p["log_incomplete"] = r.option(lambda: SINGLE_PASS[r.enum(len(SINGLE_PASS))])
    p["gated"] = r.u32()
    p["since_estimate"] = r.u32()
    p["rejects"] = {name: r.u32() for name in REJECTS}
    return p


def estimate_kind(r):
    k = r.enum(3)
    if k == 0:
        return "Running"
    if k == 1:
        return "Final(passes=%d, converged=%s)" % (r.u8(), r.bool())
    return "SinglePass(reason=%s, logged=%d)" % (SINGLE_PASS[r.enum(len(SINGLE_PASS))], r.u32())


def estimate(r):
    return dict(config=CONFIG_IDS[r.enum(7)], errors=ERROR_MODELS[r.enum(2)],
                seq=r.u32(), updates=r.u32(), state=r.vec(r.f64, MAX_STATES),
                sigma=r.vec(r.f64, MAX_STATES), progress=progress(r),
                frame_errors=r.u32(), kind=estimate_kind(r))


def checkpoint(r):
    return dict(config=CONFIG_IDS[r.enum(7)], errors=ERROR_MODELS[r.enum(2)],
                state=r.vec(r.f64, MAX_STATES), factor=r.vec(r.f64, MAX_FACTOR),
                nominal=r.option(lambda: r.vec(r.f64, MAX_STATES)),
                c_cn=r.array(r.f64, 9), updates=r.u32(), gated_run=r.u32(),
                gate_open=r.bool(), progress=progress(r))


def configure(r):
    c = dict(config=CONFIG_IDS[r.enum(7)], sigma_accel_g=r.f64(),
             sigma_gyro_rad_s=r.f64(), sigma_gimbal_rad=r.f64(),
             earth_rate_n=r.array(r.f64, 3), gravity_n=r.array(r.f64, 3),
             prior_sigma_rad=r.f64())
    c["options"] = dict(second_order_covariance=r.bool(), second_order_mean=r.bool(),
                        second_order_dynamics=r.bool(), iterations=r.u8(),
                        iterate_updates=r.u32(), nis_gate=r.f64())
    c["limits"] = dict(period_s=r.f64(), period_tolerance_s=r.f64(),
                       max_accel_g=r.f64(), max_increment_rad=r.f64(),
                       max_gimbal_rad=r.f64(), max_bridge=r.u32(),
                       frame_tolerance_rad=r.f64())
    c["estimate_every"] = r.u32()
    c["errors"] = ERROR_MODELS[r.enum(2)]
    c["instrument_prior"] = dict(dg_rad_s=r.f64(), d_g_rad_s_g=r.f64(), kg=r.f64(),
                                 ba_g=r.f64(), ka=r.f64(), k2=r.f64())
    c["wander"] = dict(gyro_markov_sigma=r.f64(), gyro_markov_tau_s=r.f64(),
                       gyro_random_walk=r.f64(), accel_markov_sigma=r.f64(),
                       accel_markov_tau_s=r.f64(), accel_random_walk=r.f64(),
                       gyro_warmup_sigma=r.f64(), accel_warmup_sigma=r.f64(),
                       warmup_tau_s=r.f64())
    return c


FILTER_ERRORS = ["NonFiniteInput", "InvalidPeriod", "MissingGimbal", "GimbalLock",
                 "InnovationNotPositiveDefinite", "CovarianceNotPositiveDefinite",
                 "NonFiniteState", "Gated", "NoPrediction", "OutOfRange",
                 "UnsupportedOption"]


CONFIG_FIELDS = ["SigmaAccel", "SigmaGyro", "SigmaGimbal", "PriorDg", "PriorDG", "PriorKg",
                 "PriorBa", "PriorKa", "PriorK2", "GyroMarkovSigma", "GyroMarkovTau",
                 "GyroRandomWalk", "AccelMarkovSigma", "AccelMarkovTau", "AccelRandomWalk",
                 "GyroWarmupSigma", "AccelWarmupSigma", "WarmupTau"]


def refusal_reason(r):
    k = r.enum(7)
    if k == 0:
        return "NotConfigured"
    if k == 1:
        return "ConfigMismatch(expected=%s, found=%s)" % (CONFIG_IDS[r.enum(7)], CONFIG_IDS[r.enum(7)])
    if k == 2:
        return "ErrorModelMismatch(expected=%s, found=%s)" % (ERROR_MODELS[r.enum(2)], ERROR_MODELS[r.enum(2)])
    if k == 3:
        return "CheckpointDimension"
    if k == 4:
        return "CheckpointInvalid"
    if k == 5:
        return "Filter(%s)" % FILTER_ERRORS[r.enum(len(FILTER_ERRORS))]
    return "InvalidField(%s)" % CONFIG_FIELDS[r.enum(len(CONFIG_FIELDS))]


def refused(r):
    return dict(message=r.u8(), reason=refusal_reason(r))


MESSAGES = [("Sample", sample), ("Estimate", estimate), ("Checkpoint", checkpoint),
            ("Configure", configure), ("Reset", None), ("CheckpointRequest", None),
            ("EstimateRequest", None), ("Finish", None), ("Refused", refused)]


def decode_frame(frame):
    """(name, fields) of a frame without its delimiter, or the reason it is rejected."""
    raw = cobs_decode(frame)
    if raw is None or len(raw) < 6:
        return "truncated"
    if zlib.crc32(raw[:-4]).to_bytes(4, "little") != raw[-4:]:
        return "corrupt"
    if raw[0] != VERSION:
        return "wrong_version"
    r = Reader(raw[1:-4])
    try:
        name, read = MESSAGES[r.enum(len(MESSAGES))]
        fields = read(r) if read else {}
    except Malformed:
        return "malformed"
    if r.i != len(r.d):
        return "malformed"  # bytes left after the message
    return name, fields


def sample_line(s):
    g = s["gimbal"]
    return " ".join([str(s["seq"]), str(s["t_us"]), s["dt"], *s["dtheta_cmd"],
                     *s["c_cn_quat"], *s["accel_mean"], *(g if g else ["none"])])


def csv_line(row):
    """A row of `host-sim record --format csv` as a `sample_line`."""
    f32 = lambda x: struct.pack("<f", float(x)).hex()  # shortest repr: exact
    f64 = lambda x: struct.pack("<d", float(x)).hex()
    sec, us = row["t_s"].split(".")
    gimbal = [row.get("gimbal_%s_rad" % a, "") for a in ("alpha", "beta", "gamma")]
    return " ".join([row["seq"], str(int(sec) * 1000000 + int(us.ljust(6, "0"))),
                     f32(row["dt_s"]), *(f64(row["dtheta_%s_rad" % a]) for a in "xyz"),
                     *(f32(row["ccn_q" + a]) for a in "wxyz"),
                     *(f32(row["accel_%s_g" % a]) for a in "xyz"),
                     *([f32(g) for g in gimbal] if all(gimbal) else ["none"])])


def cmd_stream(path, samples_out, csv_path=None):
    data = open(path, "rb").read()
    stats = dict(ok=0, truncated=0, corrupt=0, wrong_version=0, malformed=0, empty=0)
    kinds, lines = {}, []
    parts = data.split(b"\x00")
    for frame in parts[:-1]:
        if not frame:
            stats["empty"] += 1
            continue
        got = decode_frame(frame)
        if isinstance(got, str):
            stats[got] += 1
            continue
        stats["ok"] += 1
        kinds[got[0]] = kinds.get(got[0], 0) + 1
        if got[0] == "Sample":
            lines.append(sample_line(got[1]))
    print("frames " + " ".join("%s=%d" % kv for kv in stats.items()))
    print("messages " + " ".join("%s=%d" % kv for kv in sorted(kinds.items())))
    print("pending %d" % len(parts[-1]))
    if samples_out:
        with open(samples_out, "w") as f:
            f.write("".join(line + "\n" for line in lines))
    if csv_path:
        import csv
        rows = [csv_line(r) for r in csv.DictReader(open(csv_path))]
        bad = sum(a != b for a, b in zip(lines, rows)) + abs(len(lines) - len(rows))
        print("csv %d samples, %d rows, %d different" % (len(lines), len(rows), bad))
        return 1 if bad else 0
    return 0


def blocks(page, kind):
    """{name: (stated length, bytes)} of the page's `KIND (NAME): N bytes` blocks."""
    out, lines = {}, page.split("\n")
    for i, line in enumerate(lines):
        m = re.match(r"^%s \((.+)\): (\d+) bytes$" % kind, line)
        if not m:
            continue
        data = bytearray()
        for body in lines[i + 1:]:
            if not body.strip() or body.startswith("```"):
                break
            data += bytes.fromhex(body.split("  ")[0])
        out[m.group(1)] = (int(m.group(2)), bytes(data))
    return out


def cmd_doc(path):
    page = open(path, encoding="utf-8").read()
    raws = blocks(page, "raw")
    ok = True
    for name, (stated, frame) in blocks(page, "frame").items():
        if stated != len(frame) or frame[-1] != 0 or 0 in frame[:-1]:
            print("FAIL %s: not a frame of %d bytes" % (name, stated))
            ok = False
            continue
        if name in raws and raws[name][1] != cobs_decode(frame[:-1]):
            print("FAIL %s: the raw block is not the frame's COBS decoding" % name)
            ok = False
        got = decode_frame(frame[:-1])
        if isinstance(got, str):
            print("FAIL %s: %s" % (name, got))
            ok = False
            continue
        print("%s: %s %s" % (name, got[0], summary(got[1])))
    return 0 if ok else 1


def summary(fields):
    """One line: every scalar field, vectors by their length."""
    out = []
    def walk(prefix, v):
        if isinstance(v, dict):
            for k, x in v.items():
                walk(prefix + k + ".", x)
        elif isinstance(v, list) and len(v) > 4:
            out.append("%slen=%d" % (prefix, len(v)))
        else:
            out.append("%s=%s" % (prefix[:-1], v))
    walk("", fields)
    return " ".join(out)


def main(argv):
    if len(argv) >= 2 and argv[0] == "stream" and len(argv) % 2 == 0:
        opts = dict(zip(argv[2::2], argv[3::2]))
        if set(opts) - {"--samples", "--csv"}:
            print(__doc__, file=sys.stderr)
            return 2
        return cmd_stream(argv[1], opts.get("--samples"), opts.get("--csv"))
    if len(argv) == 2 and argv[0] == "doc":
        return cmd_doc(argv[1])
    print(__doc__, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
