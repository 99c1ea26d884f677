#!/usr/bin/env python3
"""Prices the Foxglove 3D topics of a recording (`/tf` and `/scene` of format 3, `/ALG/tf` and
`/ALG/scene` of format 2) (issue 38, item 12; docs/recordings.md, "3D
topics at 33 Hz"): re-chunks the recording's messages as hexcue's writer lays them out (one
chunk a second of log time, zstd level 9, 16 bytes of message index a message) under
variants, and prints the bytes of chunks and indexes of each, without rebuilding hexcue.

    python3 -m venv v && v/bin/pip install mcap zstandard foxglove-schemas-protobuf
    hexcue play --headless --trace recordings/traces/steep-turn.csv --record st.mcap
    v/bin/python scripts/price-3d-topics.py st.mcap

The sizes are simulated (the attachments and the summary are left out); the real file of a
change is measured with hexcue itself.
"""
import sys, zstandard, struct, collections
from mcap.reader import make_reader
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

path = sys.argv[1]
msgs = []
with open(path, 'rb') as f:
    r = make_reader(f)
    summ = r.get_summary()
    for schema, channel, m in r.iter_messages(log_time_order=False):
        msgs.append((channel.topic, channel.id, m.log_time, m.sequence, bytes(m.data)))
print(len(msgs), 'messages')

def chunked(msgs, level=9):
    total = 0; idx = 0
    chunk = bytearray(); t0 = None
    per_ch = collections.Counter()
    def close():
        nonlocal total, chunk
        if chunk:
            total += len(zstandard.ZstdCompressor(level=level).compress(bytes(chunk)))
        chunk = bytearray()
    for topic, cid, t, seq, data in msgs:
        if t0 is None: t0 = t
        if t - t0 >= 1e9:
            close(); t0 = t
        chunk += struct.pack('<BQHIQQ', 5, 2+4+8+8+len(data), cid, seq, t, t) + data
        idx += 16
    close()
    return total, idx

def every(msgs, n):
    # keep 3D topics only on every n-th of their drawings
    out=[]; cnt=collections.Counter()
    for m in msgs:
        if m[0].endswith('/tf') or m[0].endswith('/scene'):
            cnt[m[0]]+=1
            if (cnt[m[0]]-1) % n: continue
        out.append(m)
    return out

def variant(msgs, f):
    out=[]
    for m in msgs:
        r=f(m)
        if r is None: continue
        out.append(r)
    return out

def tf_moving_only(m):
    if m[0].endswith('/tf'):
        ft=FrameTransforms(); ft.ParseFromString(m[4])
        keep=[t for t in ft.transforms if t.child_frame_id.endswith('/platform')]
        del ft.transforms[:]; ft.transforms.extend(keep)
        return m[:4]+(ft.SerializeToString(),)
    return m

def scene_legs_only(m):
    if m[0].endswith('/scene'):
        su=SceneUpdate(); su.ParseFromString(m[4])
        keep=[e for e in su.entities if e.id.split('/')[-1]=='legs']  # 'legs' (format 2), 'ALG/legs' (3)
        del su.entities[:]; su.entities.extend(keep)
        return m[:4]+(su.SerializeToString(),)
    return m

def no_stamps(m):
    if m[0].endswith('/tf'):
        ft=FrameTransforms(); ft.ParseFromString(m[4])
        for t in ft.transforms: t.ClearField('timestamp')
        return m[:4]+(ft.SerializeToString(),)
    if m[0].endswith('/scene'):
        su=SceneUpdate(); su.ParseFromString(m[4])
        for e in su.entities: e.ClearField('timestamp')
        return m[:4]+(su.SerializeToString(),)
    return m

def q(x, bits): s=2.0**bits; return round(x*s)/s
def coarse(pbits, rbits):
    def f(m):
        if m[0].endswith('/tf'):
            ft=FrameTransforms(); ft.ParseFromString(m[4])
            for t in ft.transforms:
                if t.child_frame_id.endswith('/platform'):
                    for a in 'xyz': setattr(t.translation, a, q(getattr(t.translation,a), pbits))
                    for a in 'xyzw': setattr(t.rotation, a, q(getattr(t.rotation,a), rbits))
            return m[:4]+(ft.SerializeToString(),)
        if m[0].endswith('/scene'):
            su=SceneUpdate(); su.ParseFromString(m[4])
            for e in su.entities:
                if e.id=='legs':
                    for l in e.lines:
                        for i,p in enumerate(l.points):
                            if i%2==1:
                                for a in 'xyz': setattr(p, a, q(getattr(p,a), pbits))
            return m[:4]+(su.SerializeToString(),)
        return m
    return f


print('%-44s %10s' % ('variant', 'bytes'))
rows = [
    ('as recorded', msgs),
    ('no 3D topics', [m for m in msgs if not (m[0].endswith('/tf') or m[0].endswith('/scene'))]),
    ('3D topics at 11 Hz (every 3rd drawing)', every(msgs, 3)),
    ('tf: base -> platform only', variant(msgs, tf_moving_only)),
    ('scene: legs only', variant(msgs, scene_legs_only)),
    ('tf and scene without timestamps', variant(msgs, no_stamps)),
    ('tf base -> platform + scene legs only', variant(msgs, lambda m: tf_moving_only(scene_legs_only(m)))),
    ('drawn at 2^-12 m, 2^-16', variant(msgs, coarse(12, 16))),
    ('drawn at 2^-12 m, 2^-16, tf + legs only', variant(msgs, lambda m: coarse(12, 16)(tf_moving_only(scene_legs_only(m))))),
]
for name, ms in rows:
    print('%-44s %10d' % (name, sum(chunked(ms))))

# Chunks at level 16 (zstd's optimal parser) instead of 9, and the time each takes here.
import time
for level in (9, 16):
    started = time.time()
    chunks, indexes = chunked(msgs, level)
    print('%-44s %10d  (%.1f s to compress)' % ('as recorded, chunks at level %d' % level, chunks + indexes, time.time() - started))
