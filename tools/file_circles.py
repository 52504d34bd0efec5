#!/usr/bin/env python3
"""File circles of the workspace: source files of one crate that reach each other through their
imports (`crate::a::b`, `super::x`, a child module named from its parent), found as the strongly
connected components of the file graph. Prints each circle with its edges; exits 1 if any.

A file's `#[cfg(test)]` part is left out (tests may reach anywhere). Usage:
    tools/file_circles.py [workspace root]
"""
import collections
import os
import re
import sys

IDENT = r"[a-z_][a-z0-9_]*"


def modules(src):
    """Module path (a tuple) -> file, for every .rs file under a crate's src/."""
    out = {}
    for dirpath, _, files in os.walk(src):
        for f in files:
            if not f.endswith(".rs"):
                continue
            path = os.path.join(dirpath, f)
            parts = os.path.relpath(path, src)[:-3].split(os.sep)
            if parts[-1] in ("lib", "main", "mod"):
                parts = parts[:-1]
            out[tuple(parts)] = path
    return out


def references(mp, text, mods):
    refs = set()
    for m in re.finditer(rf"\bcrate::({IDENT}(?:::{IDENT})*)", text):
        refs.add(tuple(m.group(1).split("::")))
    for m in re.finditer(rf"use\s+crate::\{{([^}}]*)\}}", text):
        for part in m.group(1).split(","):
            head = part.strip().split("::")[0].strip()
            if re.fullmatch(IDENT, head):
                refs.add((head,))
    for m in re.finditer(rf"\b((?:super::)+)({IDENT}(?:::{IDENT})*)", text):
        up = m.group(1).count("super::")
        refs.add(mp[: len(mp) - up] + tuple(m.group(2).split("::")))
    # A child module named from its parent (`use files::x`, `files::f()`).
    for m in re.finditer(rf"(?<![:\w])({IDENT})::([A-Za-z_]\w*)", text):
        if m.group(1) not in ("crate", "super", "self") and mp + (m.group(1),) in mods:
            refs.add(mp + (m.group(1), m.group(2)))
    return refs


def circles(src):
    mods = modules(src)
    graph = collections.defaultdict(set)
    for mp, path in mods.items():
        text = open(path, encoding="utf-8").read()
        cut = text.find("#[cfg(test)]")
        text = text[:cut] if cut >= 0 else text
        text = re.sub(r"//[^\n]*", "", text)
        for r in references(mp, text, mods):
            target = next((r[:k] for k in range(len(r), 0, -1) if r[:k] in mods), None)
            if target and target != mp:
                graph[mp].add(target)
    # Tarjan's strongly connected components, iteratively.
    index, low, on, stack, found, counter = {}, {}, set(), [], [], [0]
    for root in mods:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        found.append((comp, graph))
    return found


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..")
    crates = os.path.join(root, "crates")
    total = 0
    for crate in sorted(os.listdir(crates)):
        src = os.path.join(crates, crate, "src")
        if not os.path.isdir(src):
            continue
        for comp, graph in circles(src):
            total += 1
            name = lambda m: "/".join(m) or "lib"
            print(f"{crate}: {', '.join(sorted(name(m) for m in comp))}")
            for a in sorted(comp):
                for b in sorted(graph[a] & set(comp)):
                    print(f"    {name(a)} -> {name(b)}")
    print(f"file circles: {total}")
    sys.exit(1 if total else 0)


if __name__ == "__main__":
    main()
