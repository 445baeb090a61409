"""The parse loop (isaac_lang/parse_loop.py) against lark's own parser, the reference: on every text, the same
trees, the same tokens (type, text, every position) and the positions of `propagate_positions=True`; or, on a
text with a syntax error, both reject it (the loop raises Rejected, lark the error that is then reported)."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from lark import Token, Tree
from lark.exceptions import UnexpectedInput

from isaac_lang.parse_loop import Rejected
from isaac_lang.syntax import parse_loop, reference_parser

from .test_fuzz import SEEDS, mutated_scene

ROOT = Path(__file__).resolve().parents[2]
TOKEN_FIELDS = ("type", "value", "start_pos", "end_pos", "line", "column", "end_line", "end_column")
META_FIELDS = ("line", "column", "start_pos", "end_line", "end_column", "end_pos")


def shape(node):
    """Everything of a parse tree the front end may read, as plain data."""
    if isinstance(node, Token):
        return ("token",) + tuple(getattr(node, name) for name in TOKEN_FIELDS)
    if isinstance(node, Tree):
        meta = node.meta
        where = None if meta.empty else tuple(getattr(meta, name) for name in META_FIELDS)
        return (node.data, where, [shape(child) for child in node.children])
    assert node is None, node  # a `[...]` left out
    return None


def outcome(parse, text: str, start: str):
    try:
        return shape(parse(text, start))
    except (Rejected, UnexpectedInput):
        return "rejected"


def assert_agree(text: str, start: str = "start") -> None:
    loop = outcome(parse_loop().parse, text, start)
    lark = outcome(lambda t, s: reference_parser().parse(t, start=s), text, start)
    assert loop == lark


def generated_scene() -> str:
    spec = importlib.util.spec_from_file_location("bench_parse", ROOT / "benchmarks" / "bench_parse.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench.generate(300)


@pytest.mark.parametrize("path", sorted(SEEDS), ids=lambda p: p.name)
def test_the_scenes_parse_the_same(path):
    assert_agree(SEEDS[path])


def test_a_generated_scene_parses_the_same():
    assert_agree(generated_scene())


@pytest.mark.parametrize("text", [
    "", "   \n\n", "# only a comment", "scene s { }  // a comment at the end, no newline",
    "scene s {\r\n  time 0 s .. 1 s\r\n}\r\n", "scene s {\tgravity (0, -9.81, 0) m/s2 }",
    "scene s { body b sphere { material steel  from 1  sound 2  keys 3 } }",  # keywords as property names
    "let m = 5 m\nscene s { let s = m * 2 s }",  # `m`, `s`: a name here, a unit there
    "scene s { for i in 0 .. 3 { body link{i+1}_tip sphere { radius 1 cm } } }",
    "scene s { body b sphere { radius 1 cm  at (1, 2, 3) } ",  # unclosed
    "scene s { body b sphere { radius [1] } }", "scene s { let x = 1 +* 2 }", "scene \x00",
    "scene s { let = 1 }", "include \"a.isaac\"\nscene s { use p q(a = 1) }",
])
def test_edge_cases_parse_the_same(text):
    assert_agree(text)


@pytest.mark.parametrize("text", ["-(1 + 2) * 3 m", "(1, 2, 3) m + keys cubic { 0 s: 1, 1 s: 2 }",
                                  "f(a @ (0, 1, 0), w = 2)", "2 ^ -1", "+(1)", "i+1", "1 +", ")", ""])
def test_expressions_parse_the_same(text):
    assert_agree(text, "expr")


@settings(max_examples=300, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(mutated_scene())
def test_mutated_scenes_parse_the_same(case):
    assert_agree(case[1])


@pytest.mark.slow
@settings(max_examples=5_000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_scene())
def test_mutated_scenes_parse_the_same_at_scale(case):
    assert_agree(case[1])


def test_every_state_of_the_grammar_is_one_the_loop_can_run():
    # the loop makes a state's regex and actions when a parse first comes to it: here all of them, so that a
    # grammar change the loop cannot take (a lexer callback, over 100 terminals in a state) fails here, not in
    # a user's scene that happens to reach that state
    loop = parse_loop()
    table = loop._table
    for state in table:
        actions, match, keywords = loop.states[state]
        assert set(actions) == set(table[state])
        assert callable(match) and (keywords is None or all(isinstance(k, str) for k in keywords))
    assert len(loop.states) == len(table)
