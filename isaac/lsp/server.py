"""The language server: pygls wiring of the pieces (checking.py, index.py, hover.py, completion.py, symbols.py).

Open documents live in pygls's workspace (the editor's text, saved or not). A document is checked at once when
it is opened or saved, and CHECK_DELAY after the last of a run of changes (typing does not wait for checks of
texts it has already replaced); its diagnostics, and those of the files it includes, are published then. The
index of names (for hover, definitions, references, completion, the outline) is built when a request needs it,
once per version of the document.

Positions: the front end counts lines and columns from 1, one column per character; LSP from 0, in the
client's units (UTF-16 unless it says otherwise). Both conversions go through pygls's position codec.
"""
from __future__ import annotations

import contextlib
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

from lsprotocol import types as T
from pygls.server import LanguageServer
from pygls.uris import from_fs_path, to_fs_path

from .checking import CheckResult, Finding, check_text
from .completion import FUNCTION, KEYWORD, PROPERTY, UNIT, place_of, suggestions
from .hover import hover_text
from .index import Definition, Reference, SceneIndex, build_index
from .symbols import OUTLINE_KINDS, outline
from .values import let_values

CHECK_DELAY = 0.15  # s after the last change before a document is checked again
SEVERITIES = {"error": T.DiagnosticSeverity.Error, "warning": T.DiagnosticSeverity.Warning}
COMPLETION_KINDS = {KEYWORD: T.CompletionItemKind.Keyword, PROPERTY: T.CompletionItemKind.Property,
                    UNIT: T.CompletionItemKind.Unit, FUNCTION: T.CompletionItemKind.Function}
# the order suggestions are listed in, when a client sorts by sortText
COMPLETION_ORDER = {UNIT: "0", PROPERTY: "1", KEYWORD: "2"}


@dataclass
class Analysis:
    """What the requests read of one version of a document: its index and the values of its `let`s."""

    version: int | None
    index: SceneIndex
    values: dict


@dataclass
class DocumentState:
    analysis: Analysis | None = None
    check: CheckResult | None = None
    good_scene: object = None  # the IR of the last version without errors (a body's mass while one is edited)
    pending: object = None  # the asyncio handle of the check waiting for typing to pause
    published: set = field(default_factory=set)  # the other files this document's last check published to


class IsaacLanguageServer(LanguageServer):
    def __init__(self):
        super().__init__("isaac", _version(), text_document_sync_kind=T.TextDocumentSyncKind.Incremental)
        self.states: dict = {}  # uri -> DocumentState
        self.shutdown_requested = False

    # -- documents ----------------------------------------------------------------------------------------

    def state(self, uri: str) -> DocumentState:
        return self.states.setdefault(uri, DocumentState())

    def open_texts(self) -> dict:
        """Real path -> text of every document open in the editor."""
        return {document_path(uri): doc.source for uri, doc in self.workspace.text_documents.items()}

    def read(self, path: Path) -> str | None:
        """A file's text: the editor's when it is open, else the disk's (None: it cannot be read)."""
        document = self.workspace.text_documents.get(from_fs_path(str(path)))
        if document is not None:
            return document.source
        try:
            return path.read_text(encoding="utf-8", errors="replace")
        except OSError:
            return None

    def analysis(self, uri: str) -> Analysis:
        """The index of the document as it is now (built again only when it changed)."""
        document = self.workspace.get_text_document(uri)
        state = self.state(uri)
        if state.analysis is None or state.analysis.version != document.version or document.version is None:
            index = build_index(document.source, document_path(uri), self.read)
            state.analysis = Analysis(document.version, index, let_values(index))
        return state.analysis

    # -- checking -----------------------------------------------------------------------------------------

    def check_later(self, uri: str) -> None:
        state = self.state(uri)
        if state.pending is not None:
            state.pending.cancel()
        state.pending = self.loop.call_later(CHECK_DELAY, self.check_now, uri)

    def check_now(self, uri: str) -> CheckResult | None:
        """Check a document and publish its diagnostics (an empty list clears them)."""
        state = self.state(uri)
        if state.pending is not None:
            state.pending.cancel()
            state.pending = None
        document = self.workspace.text_documents.get(uri)
        if document is None:
            return None
        path = document_path(uri)
        texts = {p: t for p, t in self.open_texts().items() if p != path}
        result = check_text(document.source, path, texts)
        state.check = result
        if result.scene is not None:
            state.good_scene = result.scene
        self.publish(uri, document, result.findings)
        return result

    def publish(self, uri: str, document, findings: list) -> None:
        path = document_path(uri)
        by_file: dict = {path: []}
        elsewhere = [f for f in findings if f.path not in (None, path)]
        for finding in findings:
            target = path if finding.path is None else finding.path
            by_file.setdefault(target, []).append(self.to_lsp(finding, target))
        if elsewhere:
            by_file[path] += self.include_notes(uri, elsewhere)
        self.publish_diagnostics(uri, by_file.pop(path), version=document.version)
        state = self.state(uri)
        for other in state.published - set(by_file):
            self.publish_diagnostics(from_fs_path(str(other)), [])
        for other, diagnostics in by_file.items():
            self.publish_diagnostics(from_fs_path(str(other)), diagnostics)
        state.published = set(by_file)

    def include_notes(self, uri: str, findings: list) -> list:
        """A diagnostic at each `include` of the document through which a file with errors is read."""
        index = self.analysis(uri).index
        notes = []
        for finding in findings:
            include = index.include_of(finding.path)
            if include is None:
                continue
            pos = finding.diagnostic.pos
            message = f"in the included {pos}: {finding.diagnostic.message}"
            notes.append(T.Diagnostic(self.range_of(include.span.path, include.span.line, include.span.col,
                                                    include.span.end_col - include.span.col),
                                      message, severity=SEVERITIES.get(finding.diagnostic.severity), source="isaac"))
        return notes

    def to_lsp(self, finding: Finding, path: Path) -> T.Diagnostic:
        diagnostic = finding.diagnostic
        message = diagnostic.message + (f"\nhint: {diagnostic.hint}" if diagnostic.hint else "")
        pos = diagnostic.pos
        if pos is None or finding.path is None:
            where = T.Range(T.Position(0, 0), T.Position(0, 0))
        else:
            where = self.range_of(path, pos.line, pos.col, pos.length)
        return T.Diagnostic(where, message, severity=SEVERITIES.get(diagnostic.severity, T.DiagnosticSeverity.Error),
                            source="isaac")

    def range_of(self, path: Path, line: int, col: int, length: int) -> T.Range:
        """The LSP range of `length` characters from a 1-based line and column of a file (a one-character place
        at the start of a word takes the whole word)."""
        document = self.workspace.get_text_document(from_fs_path(str(path)))
        lines = (self.read(path) or "").split("\n")
        text = lines[line - 1] if 0 < line <= len(lines) else ""
        start = col - 1
        end = start + max(1, length)
        if length <= 1:
            while end < len(text) and (text[end].isalnum() or text[end] == "_") and \
                    (text[start].isalnum() or text[start] == "_"):
                end += 1
        codec = document.position_codec
        return codec.range_to_client_units(lines, T.Range(T.Position(line - 1, start), T.Position(line - 1, end)))

    # -- positions ----------------------------------------------------------------------------------------

    def item_at(self, uri: str, position: T.Position):
        """(analysis, the index item under a client position)."""
        document = self.workspace.get_text_document(uri)
        here = document.position_codec.position_from_client_units(document.lines, position)
        analysis = self.analysis(uri)
        return analysis, analysis.index.at(document_path(uri), here.line + 1, here.character + 1)

    def location(self, span) -> T.Location:
        return T.Location(from_fs_path(str(span.path)),
                          self.range_of(span.path, span.line, span.col, span.end_col - span.col))


def document_path(uri: str) -> Path:
    return Path(to_fs_path(uri)).resolve()


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("isaac")
    except Exception:
        return "unknown"


server = IsaacLanguageServer()


@server.feature(T.TEXT_DOCUMENT_DID_OPEN)
def did_open(ls: IsaacLanguageServer, params: T.DidOpenTextDocumentParams):
    ls.check_now(params.text_document.uri)


@server.feature(T.TEXT_DOCUMENT_DID_CHANGE)
def did_change(ls: IsaacLanguageServer, params: T.DidChangeTextDocumentParams):
    uri = params.text_document.uri
    ls.check_later(uri)
    changed = document_path(uri)
    for other, state in ls.states.items():  # the open documents that include it
        if other != uri and state.analysis is not None and changed in state.analysis.index.files:
            state.analysis = None
            ls.check_later(other)


@server.feature(T.TEXT_DOCUMENT_DID_SAVE)
def did_save(ls: IsaacLanguageServer, params: T.DidSaveTextDocumentParams):
    ls.check_now(params.text_document.uri)


@server.feature(T.TEXT_DOCUMENT_DID_CLOSE)
def did_close(ls: IsaacLanguageServer, params: T.DidCloseTextDocumentParams):
    uri = params.text_document.uri
    state = ls.states.pop(uri, None)
    if state is not None and state.pending is not None:
        state.pending.cancel()
    for other in (state.published if state else set()) | {document_path(uri)}:
        ls.publish_diagnostics(from_fs_path(str(other)), [])


@server.feature(T.SHUTDOWN)
def shutdown(ls: IsaacLanguageServer, params=None):
    ls.shutdown_requested = True


@server.feature(T.TEXT_DOCUMENT_HOVER)
def hover(ls: IsaacLanguageServer, params: T.HoverParams):
    analysis, item = ls.item_at(params.text_document.uri, params.position)
    if item is None:
        return None
    state = ls.state(params.text_document.uri)
    scene = state.check.scene if state.check and state.check.scene else state.good_scene
    text = hover_text(analysis.index, item, analysis.values, scene)
    if text is None:
        return None
    return T.Hover(T.MarkupContent(T.MarkupKind.Markdown, text),
                   ls.range_of(item.span.path, item.span.line, item.span.col, item.span.end_col - item.span.col))


@server.feature(T.TEXT_DOCUMENT_DEFINITION)
def definition(ls: IsaacLanguageServer, params: T.DefinitionParams):
    analysis, item = ls.item_at(params.text_document.uri, params.position)
    declared = analysis.index.resolve(item) if isinstance(item, (Definition, Reference)) else None
    return ls.location(declared.span) if declared is not None else None


@server.feature(T.TEXT_DOCUMENT_REFERENCES)
def references(ls: IsaacLanguageServer, params: T.ReferenceParams):
    analysis, item = ls.item_at(params.text_document.uri, params.position)
    declared = analysis.index.resolve(item) if isinstance(item, (Definition, Reference)) else None
    if declared is None:
        return None
    spans = [r.span for r in analysis.index.uses(declared)]
    if params.context.include_declaration:
        spans.insert(0, declared.span)
    return [ls.location(span) for span in spans]


@server.feature(T.TEXT_DOCUMENT_COMPLETION, T.CompletionOptions(trigger_characters=[" "]))
def completion(ls: IsaacLanguageServer, params: T.CompletionParams):
    uri = params.text_document.uri
    document = ls.workspace.get_text_document(uri)
    here = document.position_codec.position_from_client_units(document.lines, params.position)
    place = place_of(document.source, document.offset_at_position(params.position))
    index = ls.analysis(uri).index
    scope = _scope_at(index, document_path(uri), here.line + 1)
    names = [(d.name, d.kind) for d in index.named(scope=scope) if "{" not in d.name and d.kind != "scene"]
    materials = [d.name for d in index.named(("material",), scope)]
    items = [T.CompletionItem(label=s.label, kind=COMPLETION_KINDS.get(s.kind, T.CompletionItemKind.Value),
                              detail=s.detail or None, sort_text=COMPLETION_ORDER.get(s.kind, "3") + s.label)
             for s in suggestions(place, names, materials)]
    return T.CompletionList(is_incomplete=False, items=items)


@server.feature(T.TEXT_DOCUMENT_DOCUMENT_SYMBOL)
def document_symbols(ls: IsaacLanguageServer, params: T.DocumentSymbolParams):
    uri = params.text_document.uri
    document = ls.workspace.get_text_document(uri)
    lines = document.source.split("\n")

    def symbol(item) -> T.DocumentSymbol:
        last = min(item.last_line, len(lines))
        whole = document.position_codec.range_to_client_units(
            lines, T.Range(T.Position(item.first_line - 1, 0), T.Position(last - 1, len(lines[last - 1]))))
        name = item.name_span
        return T.DocumentSymbol(name=item.name, kind=getattr(T.SymbolKind, OUTLINE_KINDS[item.kind]), range=whole,
                                selection_range=ls.range_of(name.path, name.line, name.col, name.end_col - name.col),
                                detail=item.detail, children=[symbol(child) for child in item.children])

    return [symbol(item) for item in outline(ls.analysis(uri).index)]


def _scope_at(index: SceneIndex, path: Path, line: int) -> tuple:
    """The scope of a line: that of the innermost part, loop, kind or body whose lines enclose it."""
    enclosing = [d for d in index.definitions if d.span.path == path and d.kind in ("part", "kind", "body",
                                                                                     "loop variable")
                 and d.extent[0] <= line <= d.extent[1] + 1]
    if not enclosing:
        return ()
    innermost = max(enclosing, key=lambda d: (d.extent[0], -d.extent[1]))
    return innermost.scope + (id(innermost.tree),) if innermost.kind != "loop variable" else innermost.scope


def serve() -> int:
    """Serve on stdin/stdout; the exit code the protocol asks for (0 after `shutdown`, else 1).

    The messages go out through a copy of the stdout file descriptor (pygls closes it at `exit`; the command's
    own stdout stays open to be flushed), and whatever else would print goes to stderr, never into them."""
    messages_out = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    with contextlib.redirect_stdout(sys.stderr):
        server.start_io(sys.stdin.buffer, messages_out)
    return 0 if server.shutdown_requested else 1
