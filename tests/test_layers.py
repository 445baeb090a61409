"""The layers hold (docs/design/architecture.md): the import contract of pyproject.toml ([tool.importlinter]) kept,
no import cycle among our modules, no private name imported from another module, runtime/'s top level small, and
every document the code cites present in the repository. Imports are read from the source (module level and inside
functions), not by importing."""

from __future__ import annotations

import ast
import io
import re
import shutil
import subprocess
import sys
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# package name -> its folder (pyproject's package-dir: the engine's folder is runtime/)
PACKAGES = {"isaac_ir": ROOT / "isaac_ir", "isaac_lang": ROOT / "isaac_lang", "isaac_runtime": ROOT / "runtime",
            "isaac": ROOT / "isaac"}


def our_modules() -> dict:
    """module name -> (path, is a package's __init__) of every .py file of the four packages."""
    found = {}
    for package, folder in PACKAGES.items():
        for path in folder.rglob("*.py"):
            parts = path.relative_to(folder).with_suffix("").parts
            init = parts[-1] == "__init__"
            name = ".".join((package,) + (parts[:-1] if init else parts))
            found[name] = (path, init)
    return found


MODULES = our_modules()


def imports_of(name: str) -> list:
    """[(target module, imported name or None, line)] of every import statement in the module, wherever it is."""
    path, init = MODULES[name]
    here = name if init else name.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [(alias.name, None, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = here.split(".")[: len(here.split(".")) - node.level + 1]
                base = ".".join(parent + ([node.module] if node.module else []))
            for alias in node.names:
                submodule = f"{base}.{alias.name}"
                found.append((submodule if submodule in MODULES else base, alias.name, node.lineno))
    return found


def owning_module(target: str) -> str | None:
    """The module of ours a dotted import target lands in (a name inside a module counts as the module)."""
    while target and target not in MODULES:
        target = target.rpartition(".")[0]
    return target or None


def import_graph() -> dict:
    graph = {name: set() for name in MODULES}
    for name in MODULES:
        for target, _, _ in imports_of(name):
            module = owning_module(target)
            if module is not None and module != name:
                graph[name].add(module)
    return graph


def cycles(graph: dict) -> list:
    """The strongly connected components of more than one module (Tarjan's algorithm, iterative)."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        found.append(sorted(component))
            elif child not in index:
                index[child] = low[child] = counter
                counter += 1
                stack.append(child)
                on_stack.add(child)
                work.append((child, iter(sorted(graph[child]))))
            elif child in on_stack:
                low[node] = min(low[node], index[child])
    return found


def test_the_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle():
    assert cycles(import_graph()) == []


def test_no_private_name_is_imported_from_another_module():
    crossing = [f"{name}:{line} imports {imported} from {target}" for name in MODULES
                for target, imported, line in imports_of(name)
                if imported and imported.startswith("_") and not imported.startswith("__")
                and owning_module(target) not in (None, name)]
    assert crossing == []


def test_the_engine_keeps_few_files_at_its_top_level():
    loose = sorted(path.name for path in (ROOT / "runtime").glob("*.py"))
    assert len(loose) <= 6, loose


def prose_of(path: Path) -> list:
    """[(line, text)] of the comments and docstrings of a Python file: where the code cites a document."""
    source = path.read_text(encoding="utf-8")
    found = [(token.start[0], token.string) for token in tokenize.generate_tokens(io.StringIO(source).readline)
             if token.type == tokenize.COMMENT]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value,
                                                                                                    str):
                found += [(first.lineno + i, text) for i, text in enumerate(first.value.value.splitlines())]
    return found


def test_every_document_the_code_cites_exists():
    cited = re.compile(r"(?<![\w/.-])((?:[\w.-]+/)*[\w.-]+\.md)\b")
    missing = []
    for path in [p for folder in PACKAGES.values() for p in folder.rglob("*.py")] + list(ROOT.glob("tests/**/*.py")):
        for number, text in prose_of(path):
            for document in cited.findall(text):
                if not (ROOT / document).is_file() and not any(ROOT.glob(f"docs/**/{document}")):
                    missing.append(f"{path.relative_to(ROOT)}:{number}: {document}")
    assert missing == []


def test_the_layering_contract_is_kept():
    """import-linter (a test dependency) holds the code to pyproject's contracts, indirect imports included."""
    command = Path(sys.executable).parent / "lint-imports"
    result = subprocess.run([str(command if command.exists() else shutil.which("lint-imports")), "--config",
                             str(ROOT / "pyproject.toml")], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    assert "0 broken" in result.stdout


def test_every_package_folder_is_installed():
    """Each folder of the four packages that holds an __init__.py is listed in pyproject's packages (a wheel built
    from it would miss the others)."""
    try:
        import tomllib
    except ImportError:  # Python 3.10: the tomli dependency
        import tomli as tomllib

    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {name for name, (_, init) in MODULES.items() if init}
    assert found - listed == set()
