#!/usr/bin/env python3
"""Checks the layout rules of the house (../shared/STYLE.md, "When a room grows") on src/.

  python3 tools/layout_check.py [--root DIR]

Prints one line per breach and exits 1 if there is any, 0 if none:
- a folder's mod.rs over 150 lines (a face holds declarations, re-exports and the folder's doc);
- a file over 700 lines;
- a function over 150 lines (from its `fn` line to its closing brace);
- a child module that imports a definition from a parent's mod.rs (children import siblings);
- an import cycle between the modules of one folder (a subfolder counts as one module).

It reads the code as text: `use` trees and `crate::`/`super::`/`self::` paths, each resolved to
the module file it names and, where that is a folder's face, through its `pub use` to the sibling
that defines the name. Unit-test modules (`#[cfg(test)] mod tests { ... }`) are left out: they
are not part of the structure. Only the standard library is used, so it runs on a fresh clone.
"""

import argparse
import os
import re
import sys

MOD_RS_MAX = 150
FILE_MAX = 700
FN_MAX = 150

ITEM = re.compile(
    r"^(?:pub(?:\([a-z:]+\))?\s+)?(?:async\s+|const\s+|unsafe\s+)*"
    r"(struct|enum|fn|const|static|type|trait|union)\s+([A-Za-z_][A-Za-z0-9_]*)",
    re.M,
)
MACRO = re.compile(r"^macro_rules!\s*([A-Za-z_][A-Za-z0-9_]*)", re.M)
USE = re.compile(r"\b(pub(?:\([a-z:]+\))?\s+)?use\s+([^;]+);")
PATH = re.compile(r"\b(crate|super|self)((?:\s*::\s*[A-Za-z_][A-Za-z0-9_]*)+)")
FN_LINE = re.compile(
    r"^[ \t]*(?:pub(?:\([a-z:]+\))? )?(?:async )?(?:const )?(?:unsafe )?(?:extern \"C\" )?fn ([A-Za-z0-9_]+)"
)


def strip_comments_and_strings(text):
    """The code with comments, strings and char literals blanked (line breaks kept)."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            i = j
        elif text.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if text.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif text.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            out.append("\n" * text.count("\n", i, j))
            i = j
        elif c == "r" and re.match(r'r#*"', text[i : i + 8]) and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            hashes = re.match(r"r(#*)\"", text[i:]).group(1)
            end = text.find('"' + hashes, i + 2 + len(hashes))
            end = n if end < 0 else end + 1 + len(hashes)
            out.append('""' + "\n" * text.count("\n", i, end))
            i = end
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j + 1
        elif c == "'":
            m = re.match(r"'(\\.[^']*|[^\\'])'", text[i:])
            if m:
                out.append("' '")
                i += m.end()
            else:  # a lifetime
                out.append(c)
                i += 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def drop_test_modules(code):
    """The code without `#[cfg(test)] mod name { ... }` blocks."""
    while True:
        m = re.search(r"#\[cfg\(test\)\]\s*(?:pub\s+)?mod\s+\w+\s*\{", code)
        if not m:
            return code
        depth, j = 1, m.end()
        while j < len(code) and depth:
            depth += {"{": 1, "}": -1}.get(code[j], 0)
            j += 1
        code = code[: m.start()] + "\n" * code.count("\n", m.start(), j) + code[j:]


def expand_use_tree(tree):
    """`a::{b, c::{d, e as f}}` -> [[a, b], [a, c, d], [a, c, e]] (renames dropped)."""
    tree = re.sub(r"\s+as\s+[A-Za-z_][A-Za-z0-9_]*", "", tree)
    tree = re.sub(r"\s+", "", tree)
    paths = []

    def walk(prefix, t):
        # split the top level of t by commas
        parts, depth, cur = [], 0, ""
        for ch in t:
            if ch == "{":
                depth += 1
            elif ch == "}":
                depth -= 1
            if ch == "," and depth == 0:
                parts.append(cur)
                cur = ""
            else:
                cur += ch
        if cur:
            parts.append(cur)
        for p in parts:
            if "{" in p:
                head, rest = p.split("{", 1)
                rest = rest[: rest.rfind("}")]
                head_segs = [s for s in head.split("::") if s]
                walk(prefix + head_segs, rest)
            else:
                segs = [s for s in p.split("::") if s]
                paths.append(prefix + segs)

    walk([], tree)
    return paths


class Crate:
    """One crate's module tree: module path (tuple) -> file, folder faces, definitions."""

    def __init__(self, root_file):
        self.files = {}  # module path -> file
        self.is_face = {}  # module path -> bool (lib.rs, main.rs or mod.rs)
        self.collect((), root_file, True)

    def collect(self, path, file, face):
        self.files[path] = file
        self.is_face[path] = face
        code = drop_test_modules(strip_comments_and_strings(open(file, encoding="utf-8").read()))
        folder = os.path.dirname(file) if face else os.path.splitext(file)[0]
        for m in re.finditer(r"^\s*(?:#\[[^\]]*\]\s*)*(?:pub(?:\([a-z:]+\))?\s+)?mod\s+(\w+)\s*;", code, re.M):
            name = m.group(1)
            as_file = os.path.join(folder, name + ".rs")
            as_face = os.path.join(folder, name, "mod.rs")
            if os.path.exists(as_file):
                self.collect(path + (name,), as_file, False)
            elif os.path.exists(as_face):
                self.collect(path + (name,), as_face, True)

    def resolve(self, here, segs):
        """The module a path leads to and the first name past it: (module, name or None)."""
        if not segs:
            return None
        if segs[0] == "crate":
            mod, rest = (), segs[1:]
        elif segs[0] in ("super", "self"):
            mod, rest = here, segs
            while rest and rest[0] in ("super", "self"):
                if rest[0] == "super":
                    if not mod:
                        return None
                    mod = mod[:-1]
                rest = rest[1:]
        else:
            return None
        while rest and mod + (rest[0],) in self.files:
            mod, rest = mod + (rest[0],), rest[1:]
        name = rest[0] if rest else None
        return mod, name


def analyse(crate, label, breaches):
    defs, reexports, refs = {}, {}, {}
    for mod, file in crate.files.items():
        code = drop_test_modules(strip_comments_and_strings(open(file, encoding="utf-8").read()))
        defs[mod] = {m.group(2) for m in ITEM.finditer(code)} | {m.group(1) for m in MACRO.finditer(code)}
        reexports[mod] = {}
        found = []
        for m in USE.finditer(code):
            for segs in expand_use_tree(m.group(2)):
                r = crate.resolve(mod, segs)
                if r is None:
                    continue
                found.append(r)
                if m.group(1) and segs and segs[-1] not in ("*", "self"):
                    # `pub use child::Name;` in a face: where Name really lives.
                    reexports[mod][segs[-1]] = r
        body = USE.sub(" ", code)
        for m in PATH.finditer(body):
            segs = [m.group(1)] + [s for s in re.split(r"\s*::\s*", m.group(2)) if s]
            r = crate.resolve(mod, segs)
            if r is not None:
                found.append(r)
        refs[mod] = found

    def origin(mod, name, depth=0):
        """Where a name reached through a face is defined: follows `pub use` chains."""
        if name and name in reexports.get(mod, {}) and depth < 8:
            target, tname = reexports[mod][name]
            if target != mod:
                return origin(target, tname, depth + 1)
        return mod, name

    # A child importing its parent's own definition.
    for mod, found in refs.items():
        for target, name in found:
            if target == mod or len(target) >= len(mod) or mod[: len(target)] != target:
                continue
            if name and name in defs[target] and name not in reexports[target]:
                where = "::".join(target) or "crate root"
                breaches.append(
                    f"{crate.files[mod]}: imports `{name}` defined in its parent {crate.files[target]} ({label} {where})"
                )

    # Cycles among the modules of each folder.
    for folder, face in crate.is_face.items():
        if not face:
            continue
        children = [m for m in crate.files if len(m) == len(folder) + 1 and m[: len(folder)] == folder]
        edges = {c: set() for c in children}
        for mod, found in refs.items():
            if len(mod) <= len(folder) or mod[: len(folder)] != folder:
                continue
            src = mod[: len(folder) + 1]
            for target, name in found:
                target, _ = origin(target, name)
                if len(target) <= len(folder) or target[: len(folder)] != folder:
                    continue
                dst = target[: len(folder) + 1]
                if dst != src:
                    edges[src].add(dst)
        for scc in strongly_connected(edges):
            if len(scc) > 1:
                names = ", ".join(sorted(crate.files[m] for m in scc))
                breaches.append(f"import cycle in {os.path.dirname(crate.files[folder])}/: {names}")


def strongly_connected(edges):
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            scc = []
            while True:
                w = stack.pop()
                on.discard(w)
                scc.append(w)
                if w == v:
                    break
            out.append(scc)

    for v in list(edges):
        if v not in index:
            visit(v)
    return out


def long_functions(file, breaches):
    lines = strip_comments_and_strings(open(file, encoding="utf-8").read()).split("\n")
    i = 0
    while i < len(lines):
        m = FN_LINE.match(lines[i])
        if not m:
            i += 1
            continue
        depth, opened, j = 0, False, i
        while j < len(lines):
            for ch in lines[j]:
                if ch == "{":
                    depth, opened = depth + 1, True
                elif ch == "}":
                    depth -= 1
                elif ch == ";" and not opened and depth == 0:
                    opened = None  # a declaration without a body
                    break
            if opened is None or (opened and depth == 0):
                break
            j += 1
        if opened:
            n = j - i + 1
            if n > FN_MAX:
                breaches.append(f"{file}:{i + 1}: fn {m.group(1)} is {n} lines (at most {FN_MAX})")
            i = i + 1  # nested fns are measured too
        else:
            i = j + 1


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--root", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    args = ap.parse_args()
    os.chdir(args.root)
    breaches = []
    for dirpath, _, names in sorted(os.walk("src")):
        for name in sorted(names):
            if not name.endswith(".rs"):
                continue
            file = os.path.join(dirpath, name)
            n = open(file, encoding="utf-8").read().count("\n")
            if name == "mod.rs" and n > MOD_RS_MAX:
                breaches.append(f"{file}: a folder face of {n} lines (at most {MOD_RS_MAX})")
            if n > FILE_MAX:
                breaches.append(f"{file}: {n} lines (at most {FILE_MAX})")
            long_functions(file, breaches)
    roots = [("library", "src/lib.rs")]
    for dirpath, _, names in os.walk("src/bin"):
        if "main.rs" in names:
            roots.append(("binary", os.path.join(dirpath, "main.rs")))
    for label, root in roots:
        analyse(Crate(root), label, breaches)
    for b in breaches:
        print(b)
    print(f"layout: {len(breaches)} breaches")
    return 1 if breaches else 0


if __name__ == "__main__":
    sys.exit(main())
