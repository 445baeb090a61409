"""`isaac lsp` driven over stdio with real LSP messages (tests/lsp/client.py), as an editor drives it."""
from __future__ import annotations

import time

import pytest

from .client import Client, file_uri

SCENE = """\
# a ball on a nail
let arm = 80 cm

scene demo {
  time 0 s .. 2 s
  material steel { density 7800 kg/m3  friction 0.4 }
  body ball sphere {
    radius 10
    at (0, arm, 0)
    material steel
  }
  constraint hang nail(ball @ (0, 10 cm, 0), (0, 1, 0) m)
}
"""


def line_of(text: str, needle: str) -> tuple:
    """(0-based line, 0-based column) of the first `needle` in text."""
    for number, line in enumerate(text.split("\n")):
        if needle in line:
            return number, line.index(needle)
    raise AssertionError(needle)


@pytest.fixture
def client():
    started = Client()
    yield started
    started.kill()


def test_a_conversation_from_initialize_to_exit(client, tmp_path):
    started = time.perf_counter()
    capabilities = client.initialize(tmp_path)["capabilities"]
    assert time.perf_counter() - started < 10.0  # measured 1.3-1.7 s on the loaded 2-core machine
    for provider in ("hoverProvider", "definitionProvider", "referencesProvider", "completionProvider",
                     "documentSymbolProvider"):
        assert capabilities.get(provider), provider
    uri = client.open(tmp_path / "demo.isaac", SCENE)

    # the unit mistake, where `isaac check` puts it (8:12, 1-based) and as long as the number
    diagnostics = client.diagnostics(uri, 1)
    assert len(diagnostics) == 1
    line, col = line_of(SCENE, "radius 10")
    assert diagnostics[0]["range"] == {"start": {"line": line, "character": col + 7},
                                       "end": {"line": line, "character": col + 9}}
    assert diagnostics[0]["severity"] == 1 and "unit" in diagnostics[0]["message"]
    assert "hint:" in diagnostics[0]["message"]

    # hover the `let` where the body uses it: its value in SI, with its unit
    line, col = line_of(SCENE, "at (0, arm")
    hover = client.at("textDocument/hover", uri, line, col + 8)
    assert "arm = 0.8 m" in hover["contents"]["value"]
    assert "let arm = 80 cm" in hover["contents"]["value"]

    # the definition of the body the constraint names: its declaration's line
    line, col = line_of(SCENE, "nail(ball")
    found = client.at("textDocument/definition", uri, line, col + 6)
    assert found["uri"] == uri
    assert found["range"]["start"] == {"line": line_of(SCENE, "body ball")[0], "character": 7}

    # completion at the start of a line inside the body's block: its properties
    line, _ = line_of(SCENE, "    material steel")
    items = client.at("textDocument/completion", uri, line, 4)
    labels = {item["label"] for item in (items["items"] if isinstance(items, dict) else items)}
    assert {"mass", "material", "velocity", "spin", "inertia"} <= labels
    assert "density" in labels and "gravity" not in labels  # a body's, not the scene's

    # the mistake fixed: the diagnostics cleared
    client.change(uri, SCENE.replace("radius 10", "radius 10 cm"), 2)
    assert client.diagnostics(uri, 2) == []

    assert client.close() == 0


def test_includes_nested_and_unsaved(client, tmp_path):
    """Names across nested includes; an error in an included file at its own place, and at the include."""
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "sizes.isaac").write_text('include "deeper/more.isaac"\n')
    (tmp_path / "lib" / "deeper").mkdir()
    (tmp_path / "lib" / "deeper" / "more.isaac").write_text("let side = 5 cm\nlet late = 2 s + 1 m\n")
    text = 'include "lib/sizes.isaac"\nscene s {\n  body crate box { size (side, side, side)  mass 2 kg }\n}\n'
    client.initialize(tmp_path)
    uri = client.open(tmp_path / "main.isaac", text)
    more = file_uri(tmp_path / "lib" / "deeper" / "more.isaac")

    notes = client.diagnostics(uri, 1)
    assert len(notes) == 1 and notes[0]["range"]["start"] == {"line": 0, "character": 8}  # at the include
    assert "more.isaac" in notes[0]["message"]
    inside = client.diagnostics(more)
    assert inside[0]["range"]["start"]["line"] == 1  # `isaac check` says more.isaac:2

    found = client.at("textDocument/definition", uri, 2, 26)  # `side` in the body
    assert found["uri"] == more and found["range"]["start"] == {"line": 0, "character": 4}
    hover = client.at("textDocument/hover", uri, 2, 26)
    assert "side = 0.05 m" in hover["contents"]["value"]

    # the included file edited in the editor and not saved: the scene is checked with the editor's text
    client.open(tmp_path / "lib" / "deeper" / "more.isaac", "let side = 5 cm\n")
    client.change(uri, text + "\n", 2)
    assert client.diagnostics(uri, 2) == []
    assert client.close() == 0
