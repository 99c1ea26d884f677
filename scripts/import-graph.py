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

def expand(path):
    """`a::{b, c::{d, e}}` -> [a::b, a::c::d, a::c::e]"""
    i=path.find('{')
    if i<0: return [path]
    depth=0
    for j in range(i,len(path)):
        if path[j]=='{': depth+=1
        elif path[j]=='}':
            depth-=1
            if depth==0: break
    head,body,tail=path[:i],path[i+1:j],path[j+1:]
    parts=[];depth=0;cur=''
    for ch in body:
        if ch==',' and depth==0: parts.append(cur);cur='';continue
        depth+= (ch=='{')-(ch=='}'); cur+=ch
    parts.append(cur)
    out=[]
    for q in parts:
        q=q.strip()
        if q: out+= [x for x in expand(head+q+tail)]
    return out

def resolve(m,path):
    """The module (file) a path names, seen from module m, or None."""
    path=re.sub(r'\s+','',path)
    parts=path.split('::')
    if parts[0]=='crate': base=[]; parts=parts[1:]
    elif parts[0] in ('super','self'):
        base=m.split('::') if m!='crate' else []
        while parts and parts[0] in ('super','self'):
            if parts[0]=='super': base=base[:-1]
            parts=parts[1:]
    else: return None
    full=base+parts
    for k in range(len(full),0,-1):
        c='::'.join(full[:k])
        if c in mods: return c
    return None

for m,s in files.items():
    # A test module in its own file (`mod tests;` under #[cfg(test)]) is test code too.
    if m.split('::')[-1].endswith('tests'): continue
    s=strip_tests(s)
    s=re.sub(r'//[^\n]*','',s)
    paths=[]
    for u in re.findall(r'\buse\s+([^;]+);',s,re.S):
        paths+=expand(u.split(' as ')[0] if '{' not in u else u)
    paths+=re.findall(r'\b(?:crate|super|self)(?:::[A-Za-z_][A-Za-z0-9_]*)+',s)
    for pth in paths:
        pth=re.sub(r'\s+as\s+\w+$','',pth.strip())
        r=resolve(m,pth)
        if r and r!=m: edges[m].add(r)
sys.setrecursionlimit(10000)

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
file_sccs=sccs(sorted(mods),edges)
print("file circles:",file_sccs)
top=collections.defaultdict(set)
for a,bs in edges.items():
    for b in bs:
        ta,tb=a.split('::')[0],b.split('::')[0]
        if ta!=tb: top[ta].add(tb)
print({k:sorted(v) for k,v in top.items()})

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
