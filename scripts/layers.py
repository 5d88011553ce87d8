#!/usr/bin/env python3
"""The shape of the code: import loops, wrong-way imports, the largest files and functions.

    python3 scripts/layers.py            # report
    python3 scripts/layers.py --check    # exit 1 on an import loop or a wrong-way import

A Rust file imports another when it names it by a `crate::`, `super::` or `self::` path (in a
`use` or inline), uses a child module it declares, or, from another crate of the workspace,
names it by `ggs::`. Modules are files: `src/a/b.rs` and
`src/a/b/mod.rs` are `a::b`. Test modules (`#[cfg(test)] mod tests` and `tests/`) are left
out: tests may reach anywhere. A loop is a strongly connected set of files or of top-level
modules. The layers (LAYERS below) are those of docs/architecture.md: a module may
import its own layer and those below it, never one above.

Functions are measured from their `fn` line to the closing brace, comments included.
"""
import argparse
import re
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# Bottom to top; docs/architecture.md lists the same layers.
LAYERS = [
    ["error", "threads", "simd", "rng", "memory", "order", "num"],
    ["transform", "cloud", "spacing", "thin", "mesh", "test_rng"],
    ["io", "rotations"],
    ["search", "refine"],
    ["metrics", "render"],
    ["pipeline"],
    ["settings"],
    ["align"],
    ["html"],
    # the benchmark crate (ggs-bench) sits above the whole core crate
    ["bench::"],
]


def module_of(path: Path, src: Path) -> str:
    rel = path.relative_to(src).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] in ("mod", "lib", "main"):
        parts = parts[:-1]
    return "::".join(parts)


def strip_tests(text: str) -> str:
    """Drops `#[cfg(test)] mod … { … }` blocks and comments."""
    text = re.sub(r"//[^\n]*", "", text)
    out, i = [], 0
    for m in re.finditer(r"#\[cfg\(test\)\]\s*(pub(\([\w:]+\))?\s+)?mod\s+\w+\s*\{", text):
        if m.start() < i:
            continue
        out.append(text[i:m.start()])
        depth, j = 1, m.end()
        while j < len(text) and depth:
            depth += {"{": 1, "}": -1}.get(text[j], 0)
            j += 1
        i = j
    out.append(text[i:])
    return "".join(out)


def resolve(path: str, modules: set) -> str | None:
    """The longest module prefix of a `a::b::c` path."""
    parts = path.split("::")
    for n in range(len(parts), 0, -1):
        cand = "::".join(parts[:n])
        if cand in modules:
            return cand
    return None


def use_paths(text: str, root: str) -> list:
    """Every path below `root::` (crate or ggs), with `use` groups expanded one level."""
    found = []
    for m in re.finditer(rf"\b{root}::((?:\w+::)*)\{{([^{{}}]*(?:\{{[^{{}}]*\}}[^{{}}]*)*)\}}", text):
        prefix = m.group(1)
        for item in re.split(r",(?![^{]*\})", m.group(2)):
            item = item.strip()
            if item:
                found.append(prefix + re.split(r"[\s{]", item)[0].rstrip(":"))
    for m in re.finditer(rf"\b{root}::((?:\w+)(?:::\w+)*)", text):
        if not text.startswith("::{", m.end()):  # a group's prefix: its items count
            found.append(m.group(1))
    return found


def absolute(text: str, mod: str) -> str:
    """`text` with its `super::` and `self::` paths written from `crate::` (in the file of
    module `mod`: `super::` is the module's parent, also in a `mod.rs`), and a bare `child::`
    path of a `mod child;` it declares written as `crate::mod::child::`."""
    own = mod.split("::") if mod else []

    def up(m: re.Match) -> str:
        base = own[: max(len(own) - m.group(0).count("super::"), 0)]
        return "crate::" + "".join(b + "::" for b in base)

    text = re.sub(r"\b(?:super::)+", up, text)
    text = re.sub(r"\bself::", "crate::" + "".join(o + "::" for o in own), text)
    children = re.findall(r"^\s*(?:pub(?:\([\w:]+\))?\s+)?mod\s+(\w+)\s*;", text, re.M)
    for child in children:
        full = "crate::" + "".join(o + "::" for o in own) + child + "::"
        text = re.sub(rf"(\buse\s+){child}::", rf"\g<1>{full}", text)
    return text


def crate_graph(src: Path, prefix: str, external: dict):
    files = sorted(p for p in src.rglob("*.rs"))
    modules = {module_of(p, src): p for p in files}
    graph = defaultdict(set)
    for mod, path in modules.items():
        text = strip_tests(path.read_text())
        name = prefix + mod
        for p in use_paths(absolute(text, mod), "crate"):
            tgt = resolve(p, set(modules))
            if tgt is not None and tgt != mod and tgt != "":
                graph[name].add(prefix + tgt)
        for root, (ext_prefix, ext_modules) in external.items():
            for p in use_paths(text, root):
                tgt = resolve(p, ext_modules)
                if tgt:
                    graph[name].add(ext_prefix + tgt)
        graph.setdefault(name, set())
    return modules, graph


def sccs(graph):
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
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
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def layer_of(mod: str):
    for i, names in enumerate(LAYERS):
        for n in names:
            if n.endswith("::") and mod.startswith(n):
                return i
            if mod.split("::")[0] == n:
                return i
    return None


def functions(path: Path):
    lines = path.read_text().splitlines()
    fn_re = re.compile(r"^\s*(pub(\([\w:]+\))?\s+)?(const\s+)?(unsafe\s+)?fn\s+(\w+)")
    i = 0
    while i < len(lines):
        m = fn_re.match(lines[i])
        if m:
            depth, started, j = 0, False, i
            while j < len(lines):
                code = re.sub(r"//.*", "", lines[j])
                code = re.sub(r"'(\\.|[^'\\])'", "", re.sub(r'"(\\.|[^"\\])*"', "", code))
                if not started and ";" in code and "{" not in code:
                    break  # a declaration (trait method) without a body
                depth += code.count("{") - code.count("}")
                started = started or "{" in code
                if started and depth <= 0:
                    yield m.group(5), i + 1, j - i + 1
                    break
                j += 1
        i += 1


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="exit 1 on a loop or a wrong-way import")
    ap.add_argument("--top", type=int, default=12, help="how many files and functions to list")
    args = ap.parse_args()

    core_src = ROOT / "crates/ggs/src"
    core_modules, graph = crate_graph(core_src, "", {})
    ext = {"ggs": ("", set(core_modules))}
    bench_src = ROOT / "crates/ggs-bench/src"
    if bench_src.exists():
        _, g = crate_graph(bench_src, "bench::", ext)
        graph.update(g)
        ext["ggs_bench"] = ("bench::", {module_of(p, bench_src) for p in bench_src.rglob("*.rs")})

    problems = []
    file_loops = sccs(graph)
    top = defaultdict(set)
    for a, bs in graph.items():
        for b in bs:
            ta, tb = a.split("::")[0], b.split("::")[0]
            if a.startswith("bench::"):
                ta = "bench::" + a.split("::")[1]
            if b.startswith("bench::"):
                tb = "bench::" + b.split("::")[1]
            if ta != tb:
                top[ta].add(tb)
    folder_loops = sccs(top)
    print(f"files: {len(graph)}, imports: {sum(len(v) for v in graph.values())}")
    print(f"import loops between files: {len(file_loops)}")
    for c in file_loops:
        print("   ", " <-> ".join(c))
        problems.append(c)
    print(f"import loops between top-level modules: {len(folder_loops)}")
    for c in folder_loops:
        print("   ", " <-> ".join(c))
        problems.append(c)
    wrong = []
    for a, bs in sorted(graph.items()):
        la = layer_of(a)
        for b in sorted(bs):
            lb = layer_of(b)
            if la is not None and lb is not None and lb > la:
                wrong.append(f"{a} -> {b}")
    unplaced = sorted({m.split("::")[0] for m in graph if m and layer_of(m) is None})
    print(f"wrong-way imports (a lower layer naming a higher one): {len(wrong)}")
    for w in wrong:
        print("   ", w)
    if unplaced:
        print("modules in no layer:", ", ".join(unplaced))
    problems += wrong + unplaced

    rs = [p for p in ROOT.glob("crates/*/src/**/*.rs")] + list((ROOT / "python/src").glob("*.rs"))
    sizes = sorted(((len(p.read_text().splitlines()), p.relative_to(ROOT)) for p in rs), reverse=True)
    print(f"\nlargest files (lines, tests included):")
    for n, p in sizes[: args.top]:
        print(f"  {n:5d}  {p}")
    fns = sorted(((n, f"{p.relative_to(ROOT)}:{line} {name}") for p in rs for name, line, n in functions(p)), reverse=True)
    print(f"\nlongest functions (lines):")
    for n, where in fns[: args.top]:
        print(f"  {n:5d}  {where}")
    print(f"functions over 80 lines: {sum(1 for n, _ in fns if n > 80)} of {len(fns)}")
    if args.check and problems:
        print("\nlayers.py --check: FAILED", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
