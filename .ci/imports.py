#!/usr/bin/env python3
"""The library's imports against ARCHITECTURE.md.

Reads the `use crate::…`, `crate::…` paths and `super::…` paths of every non-test source file
(test files: `tests.rs`, `test.rs`, files under a `tests` folder, `*_tests.rs`)
of crates/raisov/src (comments and deprecated re-export modules stripped) and fails, naming
the files, where
  1. two or more files import each other, directly or around a cycle, or
  2. a top-level module imports one listed above it in ARCHITECTURE.md's module list (each
     module may import only the modules listed below it), or a module is missing from it.
usage: python3 .ci/imports.py   (from the repository root)
"""
import collections
import os
import re
import sys

ROOT = "crates/raisov/src"


def modules():
    files = {}
    for dp, _, fn in os.walk(ROOT):
        for f in fn:
            if not f.endswith(".rs"):
                continue
            p = os.path.join(dp, f)
            parts = os.path.relpath(p, ROOT)[:-3].split(os.sep)
            if parts[-1] == "mod":
                parts = parts[:-1]
            if parts == ["lib"]:
                parts = []
            files["::".join(parts)] = p
    return files


def is_test(m):
    # `tests`, `test`, anything under `tests`, and `*_tests` files (test modules of one
    # concern, compiled only under #[cfg(test)]).
    last = m.split("::")[-1]
    return last in ("tests", "test") or last.endswith("_tests") or "::tests::" in m + "::"


def edges_of(files):
    mods = set(files)

    def resolve(path):
        segs = path.split("::")
        for k in range(len(segs), 0, -1):
            m = "::".join(segs[:k])
            if m in mods:
                return m
        return None

    edges = collections.defaultdict(set)
    for m, p in files.items():
        if is_test(m):
            continue
        src = open(p, encoding="utf-8").read()
        src = re.sub(r"//[^\n]*", "", src)
        # Deprecated re-exports of moved paths (`#[deprecated] pub mod old { pub use …; }`)
        # are compatibility shims for one release, not imports.
        src = re.sub(r"#\[deprecated[^\]]*\]\s*pub mod \w+ \{[^}]*\}", "", src)
        i = src.find("#[cfg(test)]\nmod tests")
        if i >= 0:
            src = src[:i]
        targets = [
            resolve(u)
            for u in re.findall(r"crate::([A-Za-z_]\w*(?:::[A-Za-z_]\w*)*)", src)
        ]
        base = m.split("::")[:-1] if m else []
        targets += [
            resolve("::".join(base + u.split("::")))
            for u in re.findall(r"\bsuper::([A-Za-z_]\w*(?:::[A-Za-z_]\w*)*)", src)
        ]
        for t in targets:
            # A module's own descendants and ancestors are its parts, not imports.
            if t and t != m and not m.startswith(t + "::") and not t.startswith(m + "::"):
                edges[m].add(t)
    return edges


def cycles(g):
    """Strongly connected components of more than one node (Tarjan)."""
    res, idx, low, st, on, c = [], {}, {}, [], set(), [0]
    sys.setrecursionlimit(10000)

    def visit(v):
        idx[v] = low[v] = c[0]
        c[0] += 1
        st.append(v)
        on.add(v)
        for w in sorted(g.get(v, ())):
            if w not in idx:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], idx[w])
        if low[v] == idx[v]:
            comp = []
            while True:
                w = st.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                res.append(sorted(comp))

    for v in sorted(g):
        if v not in idx:
            visit(v)
    return res


def architecture_order():
    text = open("ARCHITECTURE.md", encoding="utf-8").read()
    block = text.split("```")[1]
    order = []
    for line in block.splitlines():
        m = re.match(r"^  ([a-z_]+)\s{2,}\S", line)
        if m:
            order.append(m.group(1))
    return order


def main():
    files = modules()
    edges = edges_of(files)
    bad = False
    for comp in cycles(edges):
        bad = True
        print("files importing each other: " + ", ".join(files[m] for m in comp))
    order = architecture_order()
    top = collections.defaultdict(set)
    for a, bs in edges.items():
        for b in bs:
            ta, tb = a.split("::")[0], b.split("::")[0]
            if ta and tb and ta != tb:
                top[ta].add(tb)
    tops = {m.split("::")[0] for m in files if m}
    for m in sorted(tops - set(order)):
        bad = True
        print(f"module {m} is not in ARCHITECTURE.md's module list")
    for a in sorted(top):
        for b in sorted(top[a]):
            if a in order and b in order and order.index(b) < order.index(a):
                bad = True
                why = sorted(
                    files[x] for x, ys in edges.items()
                    if x.split("::")[0] == a and any(y.split("::")[0] == b for y in ys)
                )
                print(f"{a} imports {b}, listed above it in ARCHITECTURE.md ({', '.join(why)})")
    if bad:
        sys.exit(1)
    print(f"imports: {len(files)} files, no cycles, {len(order)} modules in ARCHITECTURE.md's order")


main()
