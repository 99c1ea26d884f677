#!/usr/bin/env python3
"""Where a recording's bytes go, record by record (issue 38, item 12; docs/recordings.md,
"The whole file"): every MCAP record of the file summed by kind (chunks, message indexes,
each attachment by name, each schema by name, the summary's records), then, with `--price`,
what re-encoding the chunks' own records would save under variants that keep every message.

    hexcue play --headless --trace recordings/traces/turbulence-cruise.csv --record tc.mcap
    python3 scripts/recording-breakdown.py tc.mcap                 # the standard library only
    python3 -m venv v && v/bin/pip install zstandard
    v/bin/python scripts/recording-breakdown.py tc.mcap --price     # the variants, zstd level 9

The records are read with `struct` as the MCAP specification lays them out
(https://mcap.dev/spec: an opcode byte and a u64 length before each record's body).
"""
import collections
import struct
import sys

OPS = {1: "header", 2: "footer", 3: "schema", 4: "channel", 5: "message", 6: "chunk",
       7: "message index", 8: "chunk index", 9: "attachment", 10: "attachment index",
       11: "statistics", 12: "metadata", 13: "metadata index", 14: "summary offset",
       15: "data end"}


def records(data, pos):
    while pos < len(data) - 8:
        op = data[pos]
        (length,) = struct.unpack_from("<Q", data, pos + 1)
        yield op, pos, data[pos + 9:pos + 9 + length]
        pos += 9 + length
        if op == 2:
            return


def string_at(body, at):
    (n,) = struct.unpack_from("<I", body, at)
    return body[at + 4:at + 4 + n].decode()


def breakdown(data):
    sizes, counts = collections.Counter(), collections.Counter()
    summary = False
    chunks = []
    for op, pos, body in records(data, 8):
        summary |= op == 15
        key = ("summary: " if summary and op != 15 else "") + OPS.get(op, str(op))
        if op == 9:  # log time, create time, then the name
            key += " " + string_at(body, 16)
        if op == 3:  # id u16, then the name
            key += " " + string_at(body, 2)
        if op == 6:
            chunks.append(body)
        sizes[key] += 9 + len(body)
        counts[key] += 1
    return sizes, counts, chunks


def chunk_records(body):
    """The records inside a chunk, decompressed (zstd)."""
    import zstandard
    start, end, size, crc = struct.unpack_from("<QQQI", body, 0)
    compression = string_at(body, 28)
    at = 32 + len(compression)
    (n,) = struct.unpack_from("<Q", body, at)
    raw = body[at + 8:at + 8 + n]
    if compression == "zstd":
        raw = zstandard.ZstdDecompressor().decompress(raw, max_output_size=size)
    return [(op, b) for op, _, b in records(raw, 0)]


def price(chunks):
    import zstandard
    parsed = [chunk_records(c) for c in chunks]

    def total(rs, level=9):
        out = 0
        for r in rs:
            raw = b"".join(struct.pack("<BQ", op, len(b)) + b for op, b in r)
            out += len(zstandard.ZstdCompressor(level=level).compress(raw))
        return out

    base = total(parsed)
    messages = sum(op == 5 for r in parsed for op, _ in r)
    print(f"\nchunks re-compressed at level 9: {base} B, {messages} messages")
    # One 3D message per kind for all algorithms: protobuf's repeated fields concatenate, so
    # the three FrameTransforms (SceneUpdates) of a step joined are one valid message.
    topics = {}
    for op, _, body in records(DATA, 8):
        if op == 4:
            cid, = struct.unpack_from("<H", body, 0)
            topics[cid] = string_at(body, 4)
    kind = {c: t.rsplit("/", 1)[1] for c, t in topics.items() if t.endswith(("/tf", "/scene"))}
    first = {k: min(c for c, kk in kind.items() if kk == k) for k in set(kind.values())}

    def merged(r):
        out, joined = [], {}
        for op, b in r:
            cid, seq, log, pub = struct.unpack_from("<HIQQ", b, 0) if op == 5 else (0, 0, 0, 0)
            if op == 5 and cid in kind:
                key = (first[kind[cid]], log)
                if key not in joined:
                    joined[key] = [seq, pub, bytearray()]
                    out.append(key)
                joined[key][2] += b[22:]
            else:
                out.append((op, b))
        return [(5, struct.pack("<HIQQ", x[0], joined[x][0], x[1], joined[x][1]) + bytes(joined[x][2]))
                if isinstance(x[0], int) and x in joined else x for x in out]

    joined = [merged(r) for r in parsed]
    fewer = messages - sum(op == 5 for r in joined for op, _ in r)
    saved = base - total(joined) + 16 * fewer
    print(f"one /tf and one /scene for all algorithms: {fewer} messages fewer, "
          f"{saved} B saved (chunks and 16 B of index a message)")
    for level in (16,):
        print(f"chunks at zstd level {level}: {base - total(parsed, level)} B saved")


DATA = open(sys.argv[1], "rb").read()
sizes, counts, chunks = breakdown(DATA)
for key, size in sorted(sizes.items(), key=lambda kv: -kv[1]):
    print(f"{key:45s} {counts[key]:6d} {size:10d} B {100 * size / len(DATA):6.2f} %")
print(f"{'file':45s} {'':6s} {len(DATA):10d} B")
if "--price" in sys.argv[2:]:
    price(chunks)
