"""The import graph of the package, counted: modules, edges, back edges between layers, cycles.

Every ``import`` and ``from ... import`` in the package's source files counts,
those inside functions too (an import in a function is still a dependency; it
can hide a cycle).  Layers, lowest first: ``base`` (gyrolab/'s own small
modules: the version, the build info, safe file creation), ``kernels`` (physics
and numerics), ``results`` (the file's layout and its one reader), ``analysis``
(figures, verdicts, file tools, reports: what reads stored files), ``runner``
(sweeps, which call the analysis only through its public figure step), then the
package's ``gyrolab/__init__.py`` (its public façade).  An edge from a lower
layer to a higher one is a back edge.  ``python tests/import_graph.py`` prints the counts
(docs/design.md quotes them); tests/test_structure.py holds the rules.
"""

import ast
import sys
from pathlib import Path

CHECKOUT = Path(__file__).resolve().parents[1]
SOURCES = {"kernels": "kernels", "runner": "runner", "analysis": "analysis", "gyrolab": "gyrolab"}
LAYERS = ("base", "kernels", "results", "analysis", "runner", "gyrolab")


def module_files(root=CHECKOUT):
    """{module name (without ``gyrolab.``, "" for the package itself): path} of every source file."""
    out = {}
    for top, folder in SOURCES.items():
        for path in sorted((root / folder).rglob("*.py")):
            if "__pycache__" in path.parts:
                continue
            parts = list(path.relative_to(root / folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            if top == "gyrolab":
                name = ".".join(parts)
            else:
                name = ".".join([top, *parts])
            out[name] = path
    return out


def layer(module):
    """The layer (index in LAYERS) of a module name ("" is the package's __init__; "layout" the results
    layout of checkouts from before gyrolab/results/)."""
    if not module:
        return LAYERS.index("gyrolab")
    head = module.split(".")[0]
    if head == "layout":
        return LAYERS.index("results")
    return LAYERS.index(head if head in LAYERS else "base")


def edges(root=CHECKOUT):
    """[(importer, imported, in_function)] between the package's modules."""
    files = module_files(root)
    out = []
    for name, path in files.items():
        is_package = path.name == "__init__.py"
        tree = ast.parse(path.read_text())
        functions = {
            id(n) for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef)) for n in ast.walk(f)
        }
        for node in ast.walk(tree):
            targets = []
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = name.split(".") if name else []
                    if not is_package:
                        base = base[:-1]
                    base = base[: len(base) - (node.level - 1)] if node.level > 1 else base
                    mod = ".".join([*base, *(node.module.split(".") if node.module else [])])
                elif node.module and (node.module == "gyrolab" or node.module.startswith("gyrolab.")):
                    mod = node.module[len("gyrolab.") :] if node.module != "gyrolab" else ""
                else:
                    continue
                for alias in node.names:
                    full = f"{mod}.{alias.name}" if mod else alias.name
                    if full not in files and alias.name.startswith("_") and not mod:
                        continue  # gyrolab._build_info: written at install time, not a source module
                    targets.append(full if full in files else mod)
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.startswith("gyrolab."):
                        targets.append(alias.name[len("gyrolab.") :])
            for target in targets:
                while target not in files and "." in target:
                    target = target.rsplit(".", 1)[0]
                if target in files and target != name:
                    out.append((name, target, id(node) in functions))
    return sorted(set(out))


def cycles(edge_list):
    """Strongly connected components of more than one module (Tarjan), each sorted."""
    graph = {}
    for a, b, _ in edge_list:
        graph.setdefault(a, set()).add(b)
        graph.setdefault(b, set())
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
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
    return sorted(out)


def back_edges(edge_list):
    """The edges from a lower layer to a higher one."""
    return [(a, b, f) for a, b, f in edge_list if layer(a) < layer(b)]


def summary(root=CHECKOUT):
    """{"modules", "edges", "in_functions", "back_edges", "cycles"}: the counts docs/design.md quotes."""
    e = edges(root)
    return {
        "modules": len(module_files(root)),
        "edges": len(e),
        "in_functions": sum(1 for *_, f in e if f),
        "back_edges": len(back_edges(e)),
        "cycles": len(cycles(e)),
    }


if __name__ == "__main__":
    root = Path(sys.argv[1]).resolve() if len(sys.argv) > 1 else CHECKOUT
    e = edges(root)
    print(summary(root))
    for a, b, f in back_edges(e):
        print(f"back edge: {a or 'gyrolab'} -> {b}{' (in a function)' if f else ''}")
    for comp in cycles(e):
        print("cycle:", " <-> ".join(c or "gyrolab" for c in comp))
