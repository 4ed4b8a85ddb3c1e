#!/usr/bin/env python3
"""List the import circles between the files of a Rust crate.

Usage: import_cycles.py CRATE_SRC_DIR [--quiet]

A file leans on another when it names an item of the other's module by path: `crate::a::b`
in `use` lines or in the code, `super::x` (resolved from the file's own module), and a
module's own `mod x;` children are not counted as leaning (a parent declares its children).
A parent naming a child's items (`start::launch` beside `mod start;`) leans on the child, and
a child's `use super::*` on its parent. A module's re-exports of its children's items or of another crate's (`pub use child::{Item}`,
`pub use other_crate::x`) declare its public face, as `mod x;` does, and are not counted either;
`pub use crate::...` and `pub use super::...` also bring the items into the file's scope, and count.
The script reads paths only: an `impl` block of a type in another file, and method calls, are not
seen. A circle is a set of files each reachable from the others (a strongly connected component
of more than one file). It prints each circle, its files and one reference per edge, and
exits 1 if there is any. A file's reference to its own module's items, or to its parent
module's is a child leaning on its parent: counted, since a parent that leans back on the
child closes a circle.
"""
import re
import sys
from pathlib import Path

PATH = re.compile(r"\b(crate|super)((?:::[A-Za-z_][A-Za-z0-9_]*)+)")


def module_of(src: Path, f: Path):
    rel = f.relative_to(src).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] in ("mod", "lib", "main"):
        parts = parts[:-1]
    return parts


def file_of(src: Path, modules: dict, path: list):
    """The file defining the longest module prefix of `path`."""
    for n in range(len(path), -1, -1):
        key = tuple(path[:n])
        if key in modules:
            return modules[key]
    return None


def strip_comments(text: str) -> str:
    text = re.sub(r"//[^\n]*", "", text)
    return re.sub(r"/\*.*?\*/", "", text, flags=re.S)


def main() -> int:
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    if len(args) != 1:
        print(__doc__, file=sys.stderr)
        return 2
    src = Path(args[0])
    files = sorted(p for p in src.rglob("*.rs"))
    modules = {tuple(module_of(src, f)): f for f in files}
    edges = {f: {} for f in files}
    for f in files:
        mod = module_of(src, f)
        # `super` of module `a::b` (file `a/b.rs` or `a/b/mod.rs`) is module `a`.
        here = mod
        text = strip_comments(f.read_text(encoding="utf-8"))
        # Only the code outside `#[cfg(test)] mod tests { ... }` at the end counts.
        cut = text.find("#[cfg(test)]\nmod tests")
        if cut >= 0:
            text = text[:cut]
        # A re-export of a child module's items or of another crate's declares this
        # module's public face, it does not use them; `pub use crate::...` and
        # `pub use super::...` bring the items into scope too, and count.
        text = re.sub(
            r"\bpub(\([a-z]+\))?\s+use\s+(?!crate::|super::|self::)[^;]*;", "", text
        )
        # A child module's items named from its parent (`start::launch`), and a child's
        # glob import of its parent (`use super::*`).
        for child in re.findall(r"\bmod\s+([A-Za-z_][A-Za-z0-9_]*)\s*;", text):
            g = modules.get(tuple(here + [child]))
            if g is not None and re.search(rf"(?<![A-Za-z0-9_:]){child}::[A-Za-z_*{{]", text):
                edges[f].setdefault(g, f"{child}::")
        if re.search(r"use\s+super::\*", text):
            g = file_of(src, modules, here[:-1])
            if g is not None and g != f:
                edges[f].setdefault(g, "use super::*")
        for m in PATH.finditer(text):
            root, rest = m.group(1), [p for p in m.group(2).split("::") if p]
            if root == "crate":
                target = rest
            else:
                base = here[:-1]
                while rest and rest[0] == "super":
                    base, rest = base[:-1], rest[1:]
                target = base + rest
            g = file_of(src, modules, target)
            if g is not None and g != f:
                edges[f].setdefault(g, m.group(0))
    # Strongly connected components (Tarjan).
    index, low, stack, on, comps, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            comps.append(comp)

    sys.setrecursionlimit(10000)
    for v in files:
        if v not in index:
            visit(v)
    circles = [sorted(c) for c in comps if len(c) > 1]
    for c in circles:
        print("circle: " + ", ".join(str(p.relative_to(src)) for p in c))
        for a in c:
            for b, ref in edges[a].items():
                if b in c:
                    print(f"  {a.relative_to(src)} -> {b.relative_to(src)} ({ref})")
    n_edges = sum(len(e) for e in edges.values())
    print(f"{len(files)} files, {n_edges} file-to-file references, {len(circles)} circle(s)")
    return 1 if circles else 0


if __name__ == "__main__":
    sys.exit(main())
