"""The parser (isaac_lang/syntax.py, isaac_lang/parse_loop.py): the positions the parse loop gives every tree are
the ones lark's own `propagate_positions=True` gives, on every example scene and fixture (fuzzed texts:
test_parse_loop.py)."""
from __future__ import annotations

import subprocess
import sys
from importlib import resources
from pathlib import Path

import pytest
from lark import Lark, Tree

from isaac_lang.syntax import parse_loop

ROOT = Path(__file__).resolve().parents[2]
TEXTS = sorted((ROOT / "scenes").glob("*.isaac")) + sorted((Path(__file__).parent / "data").rglob("*.isaac"))


@pytest.fixture(scope="module")
def reference() -> Lark:
    grammar = resources.files("isaac_lang.grammar").joinpath("isaac.lark").read_text(encoding="utf-8")
    return Lark(grammar, parser="lalr", propagate_positions=True, start=["start", "expr"], maybe_placeholders=True,
                cache=True)


def spans(tree, out=None) -> list:
    out = [] if out is None else out
    if isinstance(tree, Tree):
        meta = tree.meta
        out.append((tree.data, None if meta.empty else (meta.line, meta.column, meta.end_line, meta.end_column)))
        for child in tree.children:
            spans(child, out)
    else:
        out.append(tree)
    return out


@pytest.mark.parametrize("path", TEXTS, ids=lambda p: p.name)
def test_positions_match_lark(reference, path):
    text = path.read_text(encoding="utf-8")
    assert spans(parse_loop().parse(text, "start")) == spans(reference.parse(text, start="start"))


@pytest.mark.parametrize("text", ["-(1 + 2) * 3 m", "(1, 2, 3) m + keys cubic { 0 s: 1, 1 s: 2 }", "f(a @ (0, 1, 0))"])
def test_expression_positions_match_lark(reference, text):
    assert spans(parse_loop().parse(text, "expr")) == spans(reference.parse(text, start="expr"))


def test_without_hides_a_module_only_while_its_block_runs_and_only_in_its_thread():
    # (in a fresh interpreter: colorsys and wave are imported by nothing else)
    code = """
import sys
from isaac_ir.imports import without
import threading
with without("colorsys", "wave", why="a test"):
    try:
        import colorsys
    except ImportError as error:
        assert "hidden while a test is imported" in str(error)
    else:
        raise AssertionError("imported inside the block")
    # another thread is not the one whose import the block is for: it imports what it wants meanwhile
    other = threading.Thread(target=lambda: __import__("wave"))
    other.start()
    other.join()
    assert "wave" in sys.modules
import colorsys
import lark.lexer
assert not lark.lexer.has_interegular  # lark was imported by isaac_lang without it, installed or not
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_lazily_imports_a_module_whose_code_runs_at_its_first_use():
    # (in a fresh interpreter: colorsys is imported by nothing else)
    code = """
import sys
from isaac_ir.imports import lazily
lazily("colorsys")
lazily("no_such_module_here")
assert "no_such_module_here" not in sys.modules
module = sys.modules["colorsys"]
assert type(module).__name__ == "_LazyModule"  # in sys.modules, its code not run
from colorsys import rgb_to_hsv  # its first use runs it
assert type(module).__name__ == "module" and rgb_to_hsv(1.0, 0.0, 0.0) == (0.0, 1.0, 1.0)
lazily("importlib.metadata")  # a submodule: its parent package has it as an attribute, as an import leaves it
import importlib
assert importlib.metadata is sys.modules["importlib.metadata"] and "email" not in sys.modules
assert importlib.metadata.version("lark")
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
