#!/usr/bin/env python3
"""Prices layout and resolution variants of a recording (docs/recordings.md, "Format 2"): the
messages re-chunked one second a chunk (zstd, 16 B of index a message) under each variant.
    python3 -m venv v && v/bin/pip install mcap zstandard
    v/bin/python scripts/price-recording-format.py turbulence.mcap
"""
import sys, json, zstandard, struct, collections, time
from mcap.reader import make_reader
path = sys.argv[1]
msgs = []
with open(path, 'rb') as f:
    r = make_reader(f)
    for schema, channel, m in r.iter_messages(log_time_order=False):
        msgs.append((channel.topic, channel.id, m.log_time, m.sequence, bytes(m.data)))
t0=msgs[0][2]; t1=msgs[-1][2]; minutes=(t1-t0)/60e9
print(len(msgs), 'messages', round(minutes*60,2),'s')
def chunked(msgs, level=9, group=False):
    total = 0; idx = 0; chunk=[]; c0=None
    def close():
        nonlocal total, chunk
        if chunk:
            if group: chunk.sort(key=lambda x: x[0])
            b=b''.join(x[1] for x in chunk)
            total += len(zstandard.ZstdCompressor(level=level).compress(b))
        chunk = []
    for topic, cid, t, seq, data in msgs:
        if c0 is None: c0 = t
        if t - c0 >= 1e9:
            close(); c0 = t
        chunk.append((cid, struct.pack('<BQHIQQ', 5, 2+4+8+8+len(data), cid, seq, t, t) + data))
        idx += 16
    close()
    return total, idx
def show(name, ms, **kw):
    st=time.time(); c,i=chunked(ms, **kw); dt=time.time()-st
    print(f"{name:55s} chunks {c:9d} idx {i:8d} total {c+i:9d}  {(c+i)/minutes/1e6:.3f} MB/min  ({dt:.2f}s)")
    return c+i
def jmap(f):
    def g(m):
        if m[0].startswith('/') and m[4][:1]==b'{':
            d=json.loads(m[4]); r=f(m[0],d)
            if r is None: return None
            return m[:4]+(r.encode(),)
        return m
    return g
def variant(ms,f):
    out=[]
    for m in ms:
        r=f(m)
        if r is not None: out.append(r)
    return out

import math
def refmt_fixed(field, dec, topic_suffix):
    pat=re.compile(rb'"'+field.encode()+rb'":\[([^\]]*)\]')
    def rep(mm):
        vals=[v for v in mm.group(1).split(b',')]
        out=[]
        for v in vals:
            if v==b'null': out.append(v); continue
            x=float(v); out.append(('%.*f'%(dec, x)).encode() if dec>0 else str(int(round(x))).encode())
        return b'"'+field.encode()+b'":['+b','.join(out)+b']'
    def f(m):
        if m[0].endswith(topic_suffix): return m[:4]+(pat.sub(rep,m[4]),)
        return m
    return f
def drop(field, topic_suffix):
    pat=re.compile(rb',"'+field.encode()+rb'":\[[^\]]*\]')
    def f(m):
        if m[0].endswith(topic_suffix): return m[:4]+(pat.sub(b'',m[4]),)
        return m
    return f
def sig(field, digits, topic_suffix):
    pat=re.compile(rb'"'+field.encode()+rb'":\[([^\]]*)\]')
    def rep(mm):
        out=[]
        for v in mm.group(1).split(b','):
            if v==b'null': out.append(v); continue
            x=float(v); out.append(('%.*e'%(digits-1,x)).replace('e-0','e-').replace('e+0','e').replace('e+','e').encode())
        return b'"'+field.encode()+b'":['+b','.join(out)+b']'
    def f(m):
        if m[0].endswith(topic_suffix): return m[:4]+(pat.sub(rep,m[4]),)
        return m
    return f
base=show('as recorded', msgs)
topics=collections.Counter(m[0] for m in msgs)
for tname in sorted(set(k.split('/')[-1] for k in topics)):
    v=[m for m in msgs if m[0].split('/')[-1]!=tname]
    b=show(f'without */{tname}', v); print('   saves', base-b)
import re
def drop_margin(topic,d):
    return None
# textual edit keeping number formats: remove ,"margin":[...]
def nomargin(m):
    if m[0].endswith('/actuators'):
        return m[:4]+(re.sub(rb',"margin":\[[^\]]*\]', b'', m[4]),)
    return m
b=show('no margins', variant(msgs,nomargin)); print('   saves', base-b)
def us10(m):
    if m[0].endswith('/controller'):
        s=re.sub(rb'"(solve_time_us|step_time_us)":(\d+)(\.0)?', lambda x: b'"%s":%d.0'%(x.group(1), round(int(x.group(2))/10)*10), m[4])
        return m[:4]+(s,)
    return m
b=show('controller times at 10 us', variant(msgs,us10)); print('   saves', base-b)
b=show('grouped by topic in chunk', msgs, group=True); print('   saves', base-b)
for lv in (10,12,14,15):
    b=show(f'level {lv}', msgs, level=lv); print('   saves', base-b)
nm=variant(msgs, drop('margin','/actuators'))
b0=show('no margins', nm)
for name,f in [('leg velocity dropped',drop('velocity','/actuators')),('leg length dropped',drop('length','/actuators')),
  ('platform accel 2 dec',refmt_fixed('acceleration',2,'/platform')),('platform velocity dropped',drop('velocity','/platform')),('platform accel dropped',drop('acceleration','/platform')),
  ('pose 5 dec',refmt_fixed('pose',5,'/platform')),('leg length 5 dec',refmt_fixed('length',5,'/actuators')),
  ('perceived 5 sig',lambda m: sig('angular_velocity',5,'perceived')(sig('specific_force',5,'perceived')(m)))]:
    b=show('no margins + '+name, variant(nm,f)); print('   saves', b0-b)
b=show('no margins, grouped', nm, group=True); print('   saves', b0-b)
def chunked2(msgs, level=9, key=None):
    total = 0; idx = 0; chunk=[]; c0=None
    def close():
        nonlocal total, chunk
        if chunk:
            if key: chunk.sort(key=key)
            b=b''.join(x[-1] for x in chunk)
            total += len(zstandard.ZstdCompressor(level=level).compress(b))
        chunk = []
    for i,(topic, cid, t, seq, data) in enumerate(msgs):
        if c0 is None: c0 = t
        if t - c0 >= 1e9:
            close(); c0 = t
        chunk.append((topic, cid, i, struct.pack('<BQHIQQ', 5, 2+4+8+8+len(data), cid, seq, t, t) + data))
        idx += 16
    close()
    return total+idx
b0=chunked2(nm); print('no margins', b0)
kind=lambda x: (x[0].split('/')[-1], x[0], x[2])
print('by kind then lane', b0-chunked2(nm,key=kind))
print('by topic', b0-chunked2(nm,key=lambda x:(x[1],x[2])))
# json grouped by topic, 3D kept in place? group only json
print('json by topic, 3d by topic', b0-chunked2(nm,key=lambda x:(x[1],x[2])))
for lv in (6,7,8,11):
    print('by topic level',lv, b0-chunked2(nm,level=lv,key=lambda x:(x[1],x[2])))
