"""The import graph of src/ (test modules left out): circles between files and between
top-level modules, and files over 1,000 lines without their test module (issue 22).
Exits 1 when any is found. Usage: python3 scripts/import-graph.py [src]"""
import os,re,sys,collections
root=sys.argv[1] if len(sys.argv)>1 else 'src'
files={}
for d,_,fs in os.walk(root):
    for f in fs:
        if f.endswith('.rs'):
            p=os.path.join(d,f); rel=os.path.relpath(p,root)
            mod=rel[:-3].replace('/','::')
            mod=re.sub(r'(::)?mod$','',mod)
            if mod in('lib','main'): mod='crate'
            files[mod]=open(p).read()
def strip_tests(s):
    i=s.find('#[cfg(test)]')
    return s if i<0 else s[:i]
edges=collections.defaultdict(set)
mods=set(files)
for m,s in files.items():
    s=strip_tests(s)
    for mm in re.findall(r'crate::([a-z_]+(?:::[a-z_]+)*)',s):
        parts=mm.split('::')
        # longest prefix that is a module
        best=None
        for k in range(len(parts),0,-1):
            c='::'.join(parts[:k])
            if c in mods: best=c;break
        if best and best!=m: edges[m].add(best)
    # super:: usage
    for mm in re.findall(r'super::([a-z_]+)',s):
        parent='::'.join(m.split('::')[:-1]) if not files.get(m) is None else m
        base=parent if parent else ''
        c=(base+'::'+mm) if base else mm
        if c in mods and c!=m: edges[m].add(c)
# cycles among files via tarjan
idx={};low={};st=[];on=set();res=[];i=[0]
sys.setrecursionlimit(10000)
def sc(v):
    idx[v]=low[v]=i[0];i[0]+=1;st.append(v);on.add(v)
    for w in edges[v]:
        if w not in idx: sc(w);low[v]=min(low[v],low[w])
        elif w in on: low[v]=min(low[v],idx[w])
    if low[v]==idx[v]:
        c=[]
        while True:
            w=st.pop();on.discard(w);c.append(w)
            if w==v:break
        if len(c)>1: res.append(c)
for v in list(mods):
    if v not in idx: sc(v)
file_sccs=res
print("file circles:",res)
top=collections.defaultdict(set)
for a,bs in edges.items():
    for b in bs:
        ta,tb=a.split('::')[0],b.split('::')[0]
        if ta!=tb: top[ta].add(tb)
print({k:sorted(v) for k,v in top.items()})

def sccs(nodes,edges):
    idx={};low={};st=[];on=set();out=[];n=[0]
    def sc(v):
        idx[v]=low[v]=n[0];n[0]+=1;st.append(v);on.add(v)
        for w in edges.get(v,()):
            if w not in idx: sc(w);low[v]=min(low[v],low[w])
            elif w in on: low[v]=min(low[v],idx[w])
        if low[v]==idx[v]:
            c=[]
            while True:
                w=st.pop();on.discard(w);c.append(w)
                if w==v:break
            if len(c)>1: out.append(sorted(c))
    for v in nodes:
        if v not in idx: sc(v)
    return out
top_sccs=sccs(sorted(set(top)|{b for v in top.values() for b in v}),top)
print("top-level circles:",top_sccs)
big=[]
for d,_,fs in os.walk(root):
    for f in fs:
        if f.endswith('.rs'):
            if 'tests' in f: continue  # a test module in its own file
            p=os.path.join(d,f); n=strip_tests(open(p).read()).count('\n')
            if n>1000: big.append((p,n))
print("files over 1,000 lines without tests:",big)
sys.exit(1 if file_sccs or top_sccs or big else 0)
