"""Helpers of scripts/flightgear-live.sh (not in CI).

    python scripts/flightgear_live.py aileron PORT SECONDS
        Sends FlightGear's aileron command (scripts/flightgear/hexcue-aileron.xml) to
        127.0.0.1:PORT at 20 Hz: 3 s neutral, then ±0.5 doublets of varying length
        (+0.5 then -0.5 for the same time, then 2 s neutral), so that the roll rate has a
        shape that aligns in one place only; neutral at the end.

    python scripts/flightgear_live.py log PORT FILE
        Writes FlightGear's own record of its rates (scripts/flightgear/hexcue-rates.xml,
        sent over UDP to 127.0.0.1:PORT) to FILE as it comes, until killed.

    python scripts/flightgear_live.py compare RECORDING.mcap FG-RATES.csv
        Compares the roll rate hexcue recorded on its `/aircraft` topic (JSON,
        angular_velocity[0], rad/s; one value per sample used, the steps holding it merged)
        with the one FlightGear sent of the same frames to the logger
        (scripts/flightgear/hexcue-rates.xml: time, p, q, r, roll): each hexcue sample is
        paired with its FlightGear frame by the roll angle, which does not depend on the rates
        under test; then the gain (least squares of hexcue's p on FlightGear's) and the peak
        ratios over the pairs. Exit status 0 when all three are within 1 ± 5 %.
"""

import json
import math
import socket
import sys
import time

AILERON = 0.5
TOLERANCE = 0.05


def aileron(port, seconds):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    to = ("127.0.0.1", port)
    pattern = [(0.0, 3.0)]
    for half in [1.0, 1.5, 0.8, 2.0, 1.2]:
        pattern += [(AILERON, half), (-AILERON, half), (0.0, 2.0)]
    edges = []
    t = 0.0
    for value, length in pattern:
        edges.append((t, value))
        t += length
    cycle = t
    start = time.monotonic()
    k = 0
    while True:
        now = time.monotonic() - start
        if now >= seconds:
            break
        phase = now % cycle
        value = [v for (t0, v) in edges if t0 <= phase][-1]
        s.sendto(f"{value:.3f}\n".encode(), to)
        k += 1
        time.sleep(max(0.0, start + k * 0.05 - time.monotonic()))
    for _ in range(5):
        s.sendto(b"0.000\n", to)
        time.sleep(0.05)


def log(port, path):
    """Writes every datagram FlightGear sends to 127.0.0.1:PORT to PATH as it comes (a file
    output of FlightGear's own is buffered and loses its tail when FlightGear is stopped)."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", port))
    with open(path, "w", buffering=1) as out:
        while True:
            data, _ = s.recvfrom(65536)
            out.write(data.decode(errors="replace"))


def hexcue_samples(path):
    """(roll in degrees, p, q, r) of every sample hexcue used, from its `/aircraft` topic;
    consecutive steps that hold the same sample are one."""
    from mcap.reader import make_reader

    out = []
    with open(path, "rb") as f:
        for _schema, _channel, message in make_reader(f).iter_messages(topics=["/aircraft"]):
            m = json.loads(message.data)
            row = (math.degrees(m["attitude"][0]), *m["angular_velocity"])
            if any(row) and (not out or out[-1] != row):
                out.append(row)
    return out


def flightgear_samples(path):
    """(roll in degrees, p, q, r) of every frame FlightGear logged."""
    out = []
    for line in open(path):
        fields = line.strip().split(",")
        if len(fields) != 5:
            continue  # a line cut short
        try:
            t, p, q, r, roll = (float(v) for v in fields)
        except ValueError:
            continue
        out.append((roll, p, q, r))
    return out


# FlightGear's log prints the roll with 3 decimals; hexcue has the float32 FlightGear sent.
ROLL_TOLERANCE_DEG = 0.0006


def match_frames(h, f):
    """Pairs (i, j): hexcue's sample i is FlightGear's frame j, found by the roll angle (not
    by the rates under test, so that a rate in the wrong unit still pairs): the first five
    samples anchor the sequence, then each sample is looked for among the next frames (hexcue
    steps on its own clock and skips frames that arrive between two steps)."""
    def near(roll, j0, span):
        for j in range(j0, min(j0 + span, len(f))):
            if abs(f[j][0] - roll) <= ROLL_TOLERANCE_DEG:
                return j
        return None

    for i0 in range(len(h) - 5):
        for j0 in range(len(f)):
            if abs(f[j0][0] - h[i0][0]) > ROLL_TOLERANCE_DEG:
                continue
            pairs, j = [(i0, j0)], j0
            for i in range(i0 + 1, i0 + 5):
                j = near(h[i][0], j + 1, 4)
                if j is None:
                    break
                pairs.append((i, j))
            if len(pairs) < 5:
                continue
            for i in range(i0 + 5, len(h)):
                k = near(h[i][0], pairs[-1][1] + 1, 20)
                if k is not None:
                    pairs.append((i, k))
            return pairs
    return []


def compare(mcap_path, rates_path):
    import numpy as np

    h = hexcue_samples(mcap_path)
    f = flightgear_samples(rates_path)
    pairs = match_frames(h, f)
    if len(pairs) < 50:
        print(f"FAIL: {len(pairs)} of hexcue's {len(h)} samples found among FlightGear's "
              f"{len(f)} frames")
        return 1
    hp = np.array([h[i][1] for i, _ in pairs])
    fp = np.array([f[j][1] for _, j in pairs])
    gain = float(np.dot(hp, fp) / np.dot(fp, fp))
    peak_hi = float(hp.max() / fp.max())
    peak_lo = float(hp.min() / fp.min())
    # FlightGear's log prints 6 decimals of the same float hexcue decoded.
    same = int(np.sum(np.abs(hp - fp) <= 1e-6 + 1e-6 * np.abs(fp)))
    ok = all(abs(x - 1.0) <= TOLERANCE for x in (gain, peak_hi, peak_lo))
    print(
        f"roll rate p of {len(pairs)} of the {len(h)} samples hexcue used, each paired by its "
        f"roll angle with one of the {len(f)} frames FlightGear logged; {same} of them equal "
        f"to FlightGear's p to its log's 6 decimals:\n"
        f"  FlightGear p: max {fp.max():+.4f} rad/s, min {fp.min():+.4f} rad/s\n"
        f"  hexcue /aircraft p: max {hp.max():+.4f} rad/s, min {hp.min():+.4f} rad/s\n"
        f"  hexcue/FlightGear: gain {gain:.4f} (least squares), peaks {peak_hi:.4f} (max) "
        f"{peak_lo:.4f} (min): {'PASS' if ok else 'FAIL'} (1 ± {TOLERANCE:.0%})"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    if sys.argv[1] == "log":
        log(int(sys.argv[2]), sys.argv[3])
    elif sys.argv[1] == "aileron":
        aileron(int(sys.argv[2]), float(sys.argv[3]))
    elif sys.argv[1] == "compare":
        sys.exit(compare(sys.argv[2], sys.argv[3]))
    else:
        sys.exit(__doc__)
