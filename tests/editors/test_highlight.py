"""Editor support on every shipped scene: the Pygments lexer (isaac_lang/highlight.py, `pygmentize -l isaac`) and
the TextMate grammar of the VS Code extension (editors/vscode) read every scene of scenes/, of the tests' data and
of the documentation without marking anything invalid, and know the language's words."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from isaac_lang import lower, lower_constraints
from isaac_lang.syntax import KEYWORDS

from ..doc_examples import scene_examples

pygments = pytest.importorskip("pygments")
from pygments.lexers import get_lexer_by_name, get_lexer_for_filename  # noqa: E402
from pygments.token import Error  # noqa: E402

from isaac_lang import highlight  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
VSCODE = ROOT / "editors" / "vscode"
GRAMMAR = json.loads((VSCODE / "syntaxes" / "isaac.tmLanguage.json").read_text(encoding="utf-8"))
FILES = sorted((ROOT / "scenes").glob("*.isaac")) + sorted((ROOT / "tests" / "lang" / "data").rglob("*.isaac"))
TEXTS = [(p.relative_to(ROOT).as_posix(), p.read_text(encoding="utf-8")) for p in FILES] + \
        [(e.id, e.text) for e in scene_examples()]


# -- Pygments ----------------------------------------------------------------------------------------------------

def test_the_lexer_is_registered_by_entry_point():
    assert isinstance(get_lexer_by_name("isaac"), highlight.IsaacLexer)
    assert isinstance(get_lexer_for_filename("swing.isaac"), highlight.IsaacLexer)
    done = subprocess.run([str(Path(sys.executable).with_name("pygmentize")), "-l", "isaac", "-f", "html",
                           str(ROOT / "scenes" / "pendulum.isaac")], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and "<span" in done.stdout and "pendulum" in done.stdout


@pytest.mark.parametrize("name,text", TEXTS, ids=[n for n, _ in TEXTS])
def test_the_lexer_marks_nothing_invalid(name, text):
    tokens = list(get_lexer_by_name("isaac").get_tokens(text))
    assert not [value for kind, value in tokens if kind is Error]


def test_the_lexer_marks_what_the_language_cannot_hold():
    tokens = list(get_lexer_by_name("isaac").get_tokens("at [1, 2, 3];\n"))
    assert [value for kind, value in tokens if kind is Error] == ["[", "]", ";"]


def test_the_lexer_knows_the_languages_words():
    properties = set()
    for table in (lower.SETTINGS, lower.SOLVER_PROPS, lower.CAMERA_PROPS, lower.LIGHT_PROPS, lower.MATERIAL_PROPS,
                  lower.BODY_PROPS, lower.WIND_PROPS, lower.SOUND_PROPS, lower.LISTENER_PROPS, lower.AUDIO_PROPS,
                  lower_constraints.CONSTRAINT_PROPS, lower_constraints.FORCE_PROPS):
        properties |= set(table)
    assert set(highlight.KEYWORDS) == set(KEYWORDS)
    assert set(highlight.PROPERTIES) == properties
    assert set(lower.SHAPES) | set(lower.MOTIONS) <= set(highlight.CHOICES)
    grammar = (ROOT / "grammar" / "isaac.lark").read_text(encoding="utf-8")
    unit_rule = re.search(r"^UNIT\.3: /(.*)/$", grammar, re.M).group(1)
    assert unit_rule.startswith("(" + highlight._UNIT_WORD[3:-1] + ")")  # the same unit words as the grammar


# -- TextMate (VS Code) -----------------------------------------------------------------------------------------

def tm_rules() -> list:
    """(scope, compiled regex, captures) of the top-level patterns, in order (every rule is a `match`)."""
    rules = []
    for pattern in GRAMMAR["patterns"]:
        rule = GRAMMAR["repository"][pattern["include"][1:]]
        rules.append((rule.get("name"), re.compile(rule["match"], re.M), rule.get("captures", {})))
    return rules


def tm_scopes(line: str) -> list:
    """A line the way a TextMate engine reads it: at each place, the rule whose match starts first (the first
    listed of those that start together); (scope, text) of every token."""
    rules, pos, tokens = tm_rules(), 0, []
    while pos < len(line):
        best = None
        for scope, regex, captures in rules:
            found = regex.search(line, pos)
            if found and found.end() > found.start() and (best is None or found.start() < best[1].start()):
                best = (scope, found, captures)
        if best is None:
            break
        scope, found, captures = best
        if captures:
            tokens += [(captures[k]["name"], found.group(int(k))) for k in sorted(captures, key=int)]
        else:
            tokens.append((scope, found.group(0)))
        pos = found.end()
    return tokens


def test_the_extension_folder_is_complete():
    package = json.loads((VSCODE / "package.json").read_text(encoding="utf-8"))
    (language,) = package["contributes"]["languages"]
    (grammar,) = package["contributes"]["grammars"]
    assert language["id"] == grammar["language"] == "isaac" and ".isaac" in language["extensions"]
    assert grammar["scopeName"] == GRAMMAR["scopeName"] == "source.isaac"
    assert (VSCODE / grammar["path"]).is_file() and (VSCODE / language["configuration"]).is_file()
    json.loads((VSCODE / language["configuration"]).read_text(encoding="utf-8"))


def test_every_regex_of_the_grammar_compiles_and_every_include_resolves():
    for pattern in GRAMMAR["patterns"]:
        assert pattern["include"][1:] in GRAMMAR["repository"]
    for name, rule in GRAMMAR["repository"].items():
        re.compile(rule["match"])
        assert rule.get("name") or rule.get("captures"), name


@pytest.mark.parametrize("name,text", TEXTS, ids=[n for n, _ in TEXTS])
def test_the_grammar_marks_nothing_invalid(name, text):
    invalid = [(number, token) for number, line in enumerate(text.splitlines(), start=1)
               for scope, token in tm_scopes(line) if scope == "invalid.illegal.isaac"]
    assert not invalid


def test_the_grammar_reads_numbers_with_units_and_comments():
    tokens = tm_scopes("  body bob sphere { radius 5 cm  at (0, 1, 0) m }  # the bob")
    assert ("storage.type.declaration.isaac", "body") in tokens
    assert ("keyword.other.unit.isaac", "cm") in tokens and ("keyword.other.unit.isaac", "m") in tokens
    assert ("variable.parameter.property.isaac", "radius") in tokens
    assert ("comment.line.isaac", "# the bob") in tokens
    assert ("invalid.illegal.isaac", ";") in tm_scopes("mass 1 kg;")


def test_the_grammar_knows_every_keyword_of_the_language():
    """The TextMate grammar's keyword rule names exactly the parser's keywords (a new statement, `vary` or `goal`,
    is coloured as one)."""
    text = json.dumps(GRAMMAR)
    alternation = re.search(r"\(\?:(constraint\|[a-z|]+)\)", text).group(1)
    assert set(alternation.split("|")) == set(KEYWORDS)
