#!/usr/bin/env python3
"""The import edges between the files of src/ and the cycles among them.

Usage: python3 scripts/import_cycles.py [SRC_DIR] [--edges] [--prefix PATH]

An edge A -> B is a `crate::…` or `super::…` path in file A (a `use` or a path in code; comments and
`#[cfg(test)]` modules left out, and files named tests.rs) that names module file B or an item in
it; a `crate::Name` re-exported by lib.rs counts as its module. `mod child;` declarations and
relative `use child::…` paths are containment, not edges. Prints the number of files and edges and
every strongly connected component of more than one file (a cycle); `--edges` also lists the edges
(only those touching PATH with `--prefix`).
"""
import os
import re
import sys

args = [a for a in sys.argv[1:] if not a.startswith('--')]
root = args[0] if args and os.path.isdir(args[0]) else 'src'
prefix = sys.argv[sys.argv.index('--prefix') + 1] if '--prefix' in sys.argv else None

files = {}
for directory, _, names in os.walk(root):
    for name in names:
        if name.endswith('.rs'):
            path = os.path.join(directory, name)
            files[os.path.relpath(path, root)] = open(path, encoding='utf-8').read()


def module_path(relative):
    parts = relative[:-3].split('/')
    if parts[-1] in ('mod', 'lib', 'main'):
        parts = parts[:-1]
    return tuple(parts)


modules = {module_path(r): r for r in files if r != 'main.rs'}
reexports = {}
for m in re.finditer(r'pub use ([a-z_]+)::\{?([^;]*)\}?;', files.get('lib.rs', '')):
    for name in re.findall(r'[A-Za-z_][A-Za-z0-9_]*', m.group(2)):
        reexports[name] = m.group(1)


def without_tests(text):
    kept, depth, skipping, test_attribute = [], 0, False, False
    for line in text.split('\n'):
        if skipping:
            depth += line.count('{') - line.count('}')
            skipping = depth > 0
            continue
        if test_attribute and re.match(r'\s*(pub(\(\w+\))? )?mod \w+\s*\{', line):
            depth = line.count('{') - line.count('}')
            skipping = depth > 0
            test_attribute = False
            continue
        test_attribute = line.strip() == '#[cfg(test)]'
        kept.append(line)
    return re.sub(r'//[^\n]*', '', '\n'.join(kept))


def resolve(path):
    if path and path[0] in reexports and (path[0],) not in modules:
        path = (reexports[path[0]],) + tuple(path[1:])
    for k in range(len(path), 0, -1):
        if tuple(path[:k]) in modules:
            return modules[tuple(path[:k])]
    return None


edges = set()
for relative, text in files.items():
    if relative.endswith('tests.rs') or '/tests/' in relative or relative == 'test_support.rs':
        continue
    own = module_path(relative)
    pattern = (r'\b(crate|super(?:::super)*)::([A-Za-z_][A-Za-z0-9_]*(?:::[A-Za-z_][A-Za-z0-9_]*)*)'
               r'(::\{[^;]*?\})?')
    for m in re.finditer(pattern, without_tests(text)):
        head, rest, group = m.group(1), m.group(2).split('::'), m.group(3)
        base = [] if head == 'crate' else list(own[:len(own) - head.count('super')])
        tails = [rest] + ([rest + item.split('::') for item in
                           re.findall(r'([A-Za-z_][A-Za-z0-9_:]*)', group)] if group else [])
        for tail in tails:
            target = resolve(tuple(base + tail))
            if target and target != relative:
                edges.add((relative, target))

graph = {}
for a, b in edges:
    graph.setdefault(a, set()).add(b)
index, low, stack, on_stack, components = {}, {}, [], set(), []
sys.setrecursionlimit(10000)


def connect(v):
    index[v] = low[v] = len(index)
    stack.append(v)
    on_stack.add(v)
    for w in graph.get(v, ()):
        if w not in index:
            connect(w)
            low[v] = min(low[v], low[w])
        elif w in on_stack:
            low[v] = min(low[v], index[w])
    if low[v] == index[v]:
        component = []
        while True:
            w = stack.pop()
            on_stack.discard(w)
            component.append(w)
            if w == v:
                break
        if len(component) > 1:
            components.append(sorted(component))


for v in sorted(files):
    if v not in index:
        connect(v)
if '--edges' in sys.argv:
    for a, b in sorted(edges):
        if prefix is None or a.startswith(prefix) or b.startswith(prefix):
            print(a, '->', b)
print('files', len(files), 'edges', len(edges), 'cycles', len(components))
for component in components:
    if prefix is None or any(f.startswith(prefix) for f in component):
        print(len(component), 'files:', ' '.join(component))
