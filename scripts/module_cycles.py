#!/usr/bin/env python3
"""Import cycles between the modules of each crate (issue 50's "circles").

A module is a file under a crate's src/ (mod.rs stands for its folder); module A uses B
when A's code names `crate::B…` (in `use` lines or paths, comments excluded) or `super::B`.
Prints each cycle (a strongly connected component of more than one module) per crate, and
exits 1 when there is one (scripts/test.sh runs it beside clippy).
Usage: scripts/module_cycles.py [CRATE_DIR ...]   (default: every workspace crate)
"""
import os, re, sys

def modules(src):
    mods = {}
    for root, _, files in os.walk(src):
        for f in files:
            if not f.endswith('.rs'):
                continue
            rel = os.path.relpath(os.path.join(root, f), src)[:-3].split(os.sep)
            if rel[-1] == 'mod':
                rel = rel[:-1]
            if rel in (['lib'], ['main']):
                rel = []
            mods['::'.join(rel)] = os.path.join(root, f)
    return mods

def resolve(path, mods):
    """The longest module prefix of `path` (a::b::c) that is a module."""
    parts = path.split('::')
    for n in range(len(parts), 0, -1):
        m = '::'.join(parts[:n])
        if m in mods:
            return m
    return None

def edges(mods):
    out = {m: set() for m in mods}
    for m, f in mods.items():
        text = open(f).read()
        text = re.sub(r'//[^\n]*', '', text)
        # test modules inside a file do not count
        text = text.split('#[cfg(test)]')[0]
        for p in re.findall(r'crate::((?:[a-z_][a-z0-9_]*::)*[a-z_][a-z0-9_]*)', text):
            t = resolve(p, mods)
            if t is not None and t != m and not m.startswith(t + '::') and t != '':
                out[m].add(t)
        # super::x from module a::b is a::x (from a file a/b.rs; a mod.rs is its folder)
        parent = m.split('::')[:-1] if not f.endswith('mod.rs') else m.split('::')[:-1]
        for p in re.findall(r'super::((?:[a-z_][a-z0-9_]*::)*[a-z_][a-z0-9_]*)', text):
            t = resolve('::'.join(parent + [p]) if parent else p, mods)
            if t is not None and t != m and not m.startswith(t + '::') and t != '':
                out[m].add(t)
        # grouped imports: use crate::{a::X, b};
        for group in re.findall(r'use crate::\{([^}]*)\}', text):
            for p in re.findall(r'([a-z_][a-z0-9_]*(?:::[a-z_][a-z0-9_]*)*)', group):
                t = resolve(p, mods)
                if t is not None and t != m and not m.startswith(t + '::') and t != '':
                    out[m].add(t)
    return out

def sccs(g):
    index, low, stack, on, result, counter = {}, {}, [], set(), [], [0]
    def visit(v):
        index[v] = low[v] = counter[0]; counter[0] += 1
        stack.append(v); on.add(v)
        for w in g[v]:
            if w not in index:
                visit(w); low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop(); on.discard(w); comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                result.append(sorted(comp))
    sys.setrecursionlimit(10000)
    for v in g:
        if v not in index:
            visit(v)
    return result

def crates():
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..')
    out = []
    for d in ['.', 'sim', 'physics', 'recon', 'datasets', 'scene', 'model', 'eval', 'bench', 'bridge']:
        if os.path.isdir(os.path.join(root, d, 'src')):
            out.append(os.path.normpath(os.path.join(root, d)))
    return out

total = 0
for crate in sys.argv[1:] or crates():
    g = edges(modules(os.path.join(crate, 'src')))
    # collapse submodules into their top-level module's parent folder? no: file level
    for comp in sccs(g):
        total += 1
        print(f"{os.path.basename(crate)}: {' <-> '.join(comp)}")
print(f"{total} cycle(s)")
sys.exit(1 if total else 0)
