#!/usr/bin/env python3
"""A ground station written from docs/wire.md alone: it talks to
`host-sim calibrate --replies serial` over a pseudo-terminal, as it would to
the firmware over a UART, and prints the exchange (requests sent, replies
decoded).

    tools/ground_station.py --host-sim PATH --stream STREAM.bin [--json OUT]

STREAM.bin is a recorded M1-pa stream (`host-sim record`: one Configure and
the samples). The station opens a pty pair (os.openpty, raw mode), starts
`host-sim calibrate --input /dev/pts/N --replies serial --idle-timeout 2`
on the slave, and sends, on the master:

 1. the stream's Configure and its first half of the samples (the
    calibrator sends a running Estimate every `estimate_every` samples);
 2. EstimateRequest (an Estimate back), CheckpointRequest (a Checkpoint);
 3. a Configure with an Earth rate of 2e-3 rad/s (refused: Refused,
    Filter(OutOfRange)) and the checkpoint it got back with its
    configuration changed to M4-pa (refused: Refused, ConfigMismatch);
 4. the rest of the samples, then Finish (the final Estimate).

Every frame the station builds (the requests, the two altered messages) is
built from the page: COBS(version, postcard payload, CRC-32 little-endian),
then 0x00. The replies are decoded by tools/wire_decode.py (also written
from the page). Prints one line per message each way and `replies:` with
the count of each kind; exits 1 unless every expected reply came back.
"""

import os
import struct
import subprocess
import sys
import threading
import time
import tty
import zlib

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import wire_decode  # noqa: E402  (the decoder written from the page)

VERSION = wire_decode.VERSION
TAGS = {"Reset": 4, "CheckpointRequest": 5, "EstimateRequest": 6, "Finish": 7}


def cobs_encode(raw):
    """COBS as docs/wire.md §Frame describes it (blocks of at most 254
    non-zero bytes, each after its code byte), then the 0x00 delimiter."""
    out, block = bytearray(), bytearray()
    for b in raw:
        if b == 0:
            out.append(len(block) + 1)
            out += block
            block = bytearray()
        else:
            block.append(b)
            if len(block) == 254:
                out.append(0xFF)
                out += block
                block = bytearray()
    out.append(len(block) + 1)
    out += block
    return bytes(out) + b"\x00"


def frame_of_raw(raw_without_crc):
    """A frame from version and payload: the CRC appended, COBS, delimiter."""
    crc = zlib.crc32(raw_without_crc).to_bytes(4, "little")
    return cobs_encode(raw_without_crc + crc)


def request(name):
    """A message without fields: version, its tag."""
    return frame_of_raw(bytes([VERSION, TAGS[name]]))


def raw_of(frame):
    """The raw bytes (version, payload, CRC) of a frame with its delimiter."""
    return wire_decode.cobs_decode(frame[:-1])


def altered(frame, offset, new_bytes):
    """The frame with `new_bytes` written at `offset` of its raw bytes and
    the CRC made again."""
    raw = bytearray(raw_of(frame)[:-4])
    raw[offset:offset + len(new_bytes)] = new_bytes
    return frame_of_raw(bytes(raw))


class Replies(threading.Thread):
    """Reads the master side and decodes every complete frame."""

    def __init__(self, fd):
        super().__init__(daemon=True)
        self.fd, self.buf, self.frames, self.lock = fd, bytearray(), [], threading.Lock()
        self.stop = False

    def run(self):
        while not self.stop:
            try:
                data = os.read(self.fd, 4096)
            except OSError:
                return
            if not data:
                return
            self.buf += data
            while b"\x00" in self.buf:
                i = self.buf.index(b"\x00")
                frame = bytes(self.buf[:i + 1])
                del self.buf[:i + 1]
                if len(frame) > 1:
                    with self.lock:
                        self.frames.append(frame)

    def wait_for(self, name, count, timeout=30.0):
        """Waits until `count` replies of kind `name` have come."""
        end = time.time() + timeout
        while time.time() < end:
            with self.lock:
                n = sum(1 for f in self.frames if kind(f) == name)
            if n >= count:
                return True
            time.sleep(0.02)
        return False


def kind(frame):
    got = wire_decode.decode_frame(frame[:-1])
    return got if isinstance(got, str) else got[0]


def describe(frame):
    got = wire_decode.decode_frame(frame[:-1])
    if isinstance(got, str):
        return "(rejected frame: %s)" % got
    name, f = got
    if name == "Estimate":
        return "Estimate %s seq=%d updates=%d accepted=%d state[0]=%s" % (
            f["kind"], f["seq"], f["updates"], f["progress"]["accepted"],
            struct.unpack("<d", bytes.fromhex(f["state"][0]))[0] if f["state"] else "-")
    if name == "Checkpoint":
        return "Checkpoint config=%s updates=%d factor.len=%d" % (
            f["config"], f["updates"], len(f["factor"]))
    if name == "Refused":
        return "Refused message=%d reason=%s" % (f["message"], f["reason"])
    return name


def main(argv):
    args = dict(zip(argv[::2], argv[1::2]))
    if "--host-sim" not in args or "--stream" not in args or len(argv) % 2:
        print(__doc__, file=sys.stderr)
        return 2
    frames = [f + b"\x00" for f in open(args["--stream"], "rb").read().split(b"\x00")[:-1] if f]
    configure, samples = frames[0], frames[1:]
    assert kind(configure) == "Configure", "the stream starts with its Configure"

    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    cmd = [args["--host-sim"], "calibrate", "--input", path, "--replies", "serial",
           "--idle-timeout", "2"]
    if "--json" in args:
        cmd += ["--json", args["--json"]]
    host = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    # Wait until calibrate has the device open (bytes before would wait in
    # the pty anyway).
    for _ in range(1500):
        fds = "/proc/%d/fd" % host.pid
        if os.path.isdir(fds) and any(
                os.path.realpath(os.path.join(fds, f)) == path for f in os.listdir(fds)):
            break
        time.sleep(0.02)
    reader = Replies(master)
    reader.start()

    def send(frame, what=None):
        os.write(master, frame)
        print("-> %s" % (what or describe(frame)))

    half = len(samples) // 2
    send(configure, "Configure (the stream's, %d bytes)" % len(configure))
    for f in samples[:half]:
        os.write(master, f)
    print("-> %d Samples" % half)
    send(request("EstimateRequest"), "EstimateRequest")
    send(request("CheckpointRequest"), "CheckpointRequest")
    ok = reader.wait_for("Checkpoint", 1)
    with reader.lock:
        checkpoint = next(f for f in reader.frames if kind(f) == "Checkpoint")
    # Configure's earth_rate_n[0] is at raw offset 27: version, tag,
    # config (one varint byte), then three f64 noise levels.
    send(altered(configure, 27, struct.pack("<d", 2e-3)),
         "Configure with earth_rate_n = [2e-3, …] rad/s")
    # A Checkpoint's config is the byte after version and tag: M4-pa (5).
    send(altered(checkpoint, 2, bytes([5])), "Checkpoint (the one received, config changed to M4-pa)")
    for f in samples[half:]:
        os.write(master, f)
    print("-> %d Samples" % (len(samples) - half))
    send(request("Finish"), "Finish")
    ok = reader.wait_for("Refused", 2) and ok
    ok = reader.wait_for("Estimate", 3) and ok
    # The final answer: an Estimate of kind Final after the Finish.
    end = time.time() + 60
    while time.time() < end:
        with reader.lock:
            done = any(kind(f) == "Estimate" and "Final" in describe(f) for f in reader.frames)
        if done:
            break
        time.sleep(0.05)
    # calibrate ends at its idle timeout; the master stays open until then.
    status = host.wait(timeout=120)
    reader.stop = True
    err = host.stderr.read().decode()
    os.close(master)
    os.close(slave)
    counts = {}
    with reader.lock:
        replies = list(reader.frames)
    run = []  # consecutive running estimates, printed as one line

    def flush():
        if len(run) == 1:
            print("<- %s" % describe(run[0]))
        elif run:
            seqs = [wire_decode.decode_frame(f[:-1])[1]["seq"] for f in run]
            print("<- Estimate Running x%d: seq %d ... %d" % (len(run), seqs[0], seqs[-1]))
        run.clear()

    for f in replies:
        k = kind(f)
        if k == "Estimate":
            k = "Estimate " + wire_decode.decode_frame(f[:-1])[1]["kind"].split("(")[0]
        counts[k] = counts.get(k, 0) + 1
        if k == "Estimate Running":
            run.append(f)
            continue
        flush()
        print("<- %s" % describe(f))
    flush()
    print("replies: " + " ".join("%s=%d" % kv for kv in sorted(counts.items())))
    print("calibrate exit status %d" % status)
    want = {"Checkpoint": 1, "Refused": 2, "Estimate Final": 1}
    ok = ok and status == 0 and all(counts.get(k, 0) >= n for k, n in want.items()) \
        and counts.get("Estimate Running", 0) >= 2
    if not ok:
        print(err, file=sys.stderr)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
