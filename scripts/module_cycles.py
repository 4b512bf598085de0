#!/usr/bin/env python3
"""Import circles in src/: fails (exit 1) when modules that share a parent use each other
in a circle, directly or through siblings, and prints the circle with one use per edge.

A module "uses" a sibling when any file under it names a path under the sibling (`crate::`
or `super::` paths, in code, not comments or unit tests). A module and its own parts (parent
and child) are one unit, not siblings: a child using its parent's types is how a module is
built. So the graph checked is, at every level of the tree, the one between the children of
one module; `cmd` (the binary's) is checked like the library.

    scripts/module_cycles.py [SRC_DIR] [EXCLUDED_TOP_MODULE ...]
"""
import os, re, sys, collections

def module_of(root, path):
    rel = os.path.relpath(path, root)[:-3].split(os.sep)
    if rel[-1] == "mod":
        rel = rel[:-1]
    if rel in (["lib"], ["main"]):
        return ()
    return tuple(rel)

def strip(src):
    src = re.sub(r"/\*.*?\*/", "", src, flags=re.S)
    lines = []
    for l in src.split("\n"):
        # drop line comments (not inside strings: good enough for this code base)
        i = l.find("//")
        lines.append(l if i < 0 else l[:i])
    src = "\n".join(lines)
    # unit tests may use anything: cut `#[cfg(test)] mod tests { ... }` to the end of file
    m = re.search(r"#\[cfg\(test\)\]\s*(pub\s+)?mod\s+\w+\s*\{", src)
    return src[: m.start()] if m else src

def main(root, exclude):
    modules = {}
    for d, _, files in os.walk(root):
        for f in files:
            if f.endswith(".rs"):
                p = os.path.join(d, f)
                modules[module_of(root, p)] = p
    known = set(modules)
    def resolve(path):
        # longest known module prefix of a path
        for n in range(len(path), 0, -1):
            if tuple(path[:n]) in known:
                return tuple(path[:n])
        return None
    edges = collections.defaultdict(set)
    where = {}
    for mod, p in modules.items():
        if mod and mod[0] in exclude:
            continue
        src = strip(open(p, encoding="utf-8").read())
        refs = []
        for m in re.finditer(r"\bcrate((?:::\w+)+)", src):
            refs.append(list(m.group(1).split("::")[1:]))
        for m in re.finditer(r"\b((?:super::)+)((?:\w+::)*\w+)", src):
            ups = m.group(1).count("super::")
            base = list(mod[: len(mod) - ups]) if ups <= len(mod) else None
            if base is not None:
                refs.append(base + m.group(2).split("::"))
        for r in refs:
            tgt = resolve(r)
            if tgt is None or (tgt and tgt[0] in exclude):
                continue
            # common prefix
            k = 0
            while k < min(len(mod), len(tgt)) and mod[k] == tgt[k]:
                k += 1
            if k == len(mod) or k == len(tgt):
                continue  # ancestor/descendant: a module and its own parts
            a, b = mod[: k + 1], tgt[: k + 1]
            edges[a].add(b)
            where.setdefault((a, b), (p, "::".join(r)))
    # Tarjan over every sibling graph at once (edges only join siblings)
    index, low, stack, on, sccs = {}, {}, [], set(), []
    counter = [0]
    sys.setrecursionlimit(100000)
    def visit(v):
        index[v] = low[v] = counter[0]; counter[0] += 1
        stack.append(v); on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w); low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            c = []
            while True:
                w = stack.pop(); on.discard(w); c.append(w)
                if w == v: break
            if len(c) > 1:
                sccs.append(c)
    for v in list(edges):
        if v not in index:
            visit(v)
    for c in sccs:
        names = sorted("::".join(x) for x in c)
        print("cycle:", ", ".join(names))
        members = set(c)
        for a in sorted(c):
            for b in sorted(edges[a] & members):
                p, r = where[(a, b)]
                print(f"  {'::'.join(a)} -> {'::'.join(b)}  ({os.path.relpath(p)}: {r})")
    if not sccs:
        print(f"no import circle among the {len(modules)} modules of {root}")
    return 1 if sccs else 0

if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "src", set(sys.argv[2:])))
