"""Where a scene declares and uses its names: an index of a document and the files it includes, built from the
front end's parse trees (isaac_lang.syntax), for hover, go to definition, references, completion and the outline.

Names are scoped as the expander scopes them (isaac_lang/expand.py): a `part` definition, a `for` loop, a `kind`
and a body's block each open a scope; a name used in a scope means its innermost declaration around it. A body
declared in a part is reached from outside as `INSTANCE.NAME`; a name written with `{i}` pieces (`link{i}`)
stands for every `link0`, `link1`, ... a loop makes.
"""
from __future__ import annotations

import itertools
import re
from dataclasses import dataclass, field
from pathlib import Path

from lark import Token, Tree

from isaac_lang import vocabulary
from isaac_ir.diagnostics import Reporter
from isaac_lang.syntax import parse_text

# declarations that open with `KEYWORD NAME`: kind of symbol -> the property table of its block (None: no block
# of properties)
DECLARATION_TABLES = {
    "material": vocabulary.MATERIAL_PROPS, "body": vocabulary.BODY_PROPS, "constraint": vocabulary.CONSTRAINT_PROPS,
    "force": vocabulary.FORCE_PROPS, "wind": vocabulary.WIND_PROPS, "sound": vocabulary.SOUND_PROPS,
    "camera": vocabulary.CAMERA_PROPS, "light": vocabulary.LIGHT_PROPS, "scene": None,
}
# blocks that a property or a setting opens: its name -> its table
NESTED_TABLES = {"listener": vocabulary.LISTENER_PROPS, "audio": vocabulary.AUDIO_PROPS}
# the words that name a table in hovers (`a property of a body`)
TABLE_OWNERS = {id(table): kind for kind, table in DECLARATION_TABLES.items() if table is not None}
TABLE_OWNERS.update({id(vocabulary.SETTINGS): "the scene", id(vocabulary.SOLVER_PROPS): "the solver",
                     id(vocabulary.LISTENER_PROPS): "the listener", id(vocabulary.AUDIO_PROPS): "the audio settings",
                     id(vocabulary.PART_PROPS): "a part of a compound body"})


@dataclass(frozen=True)
class Span:
    """A stretch of one line of a file: 1-based line, 1-based columns, `end_col` just after it (as the lexer
    counts columns: one per character)."""

    path: Path
    line: int
    col: int
    end_col: int

    def contains(self, path: Path, line: int, col: int) -> bool:
        return path == self.path and line == self.line and self.col <= col <= self.end_col


@dataclass
class Definition:
    """A declared name: what it is (`let`, `body`, `material`, `constraint`, `kind`, `part`, `instance`,
    `parameter`, `loop variable`, `piece`, ...), where its name is written, the tree of its declaration."""

    kind: str
    name: str
    span: Span
    scope: tuple  # the scopes it is declared in, outermost first (ids of their trees)
    order: int  # its place in the expanded text (includes spliced where they stand)
    tree: Tree
    header: str = ""  # its first line as written
    extent: tuple = None  # (first line, last line) of the whole declaration, in its file
    part: str | None = None  # an instance: the part it uses
    # the scopes it is visible in: its own for the scoped names (lets, parameters, loop variables, kinds, parts);
    # for the scene's names (bodies, materials, constraints, ...) the innermost part around it, loops aside
    visible: tuple = ()

    def matches(self, name: str) -> bool:
        """Whether `name` (as used) is this name, one of the names a `{i}` template makes, or the template written
        again (`link{i}` in a loop; `link{i+1}` too)."""
        if "{" in name:
            return _NAME_PIECES.sub("{}", name) == _NAME_PIECES.sub("{}", self.name)
        if "{" not in self.name:
            return name == self.name
        return template_pattern(self.name).fullmatch(name) is not None


@dataclass
class Reference:
    """A name used: `name` as written at `span`; `owner` the instance it is read through (`left.tip`: `left`)."""

    name: str
    span: Span
    scope: tuple
    order: int
    role: str = "value"  # value | call (a kind or a constraint of the library) | part (`use PART`)
    owner: "Reference | None" = None


@dataclass
class PropertyKey:
    """A property written in a block: its key, the table of the block it stands in, and the value's tree."""

    name: str
    span: Span
    table: dict
    value: object


@dataclass
class Include:
    """`include "FILE"`: the file it names (resolved beside the including file) and where it is written."""

    target: Path
    span: Span


@dataclass
class SceneIndex:
    root: Path
    definitions: list = field(default_factory=list)
    references: list = field(default_factory=list)
    properties: list = field(default_factory=list)
    includes: list = field(default_factory=list)
    part_scopes: set = field(default_factory=set)  # the scopes that `part` definitions open
    files: dict = field(default_factory=dict)  # path -> text, every file indexed (the root's first)
    trees: dict = field(default_factory=dict)  # path -> parse tree (None: a syntax error)

    # -- lookups ------------------------------------------------------------------------------------------

    def at(self, path: Path, line: int, col: int):
        """The Definition, Reference or PropertyKey written at a place (1-based), or None."""
        for item in itertools.chain(self.references, self.definitions, self.properties):
            if item.span.contains(path, line, col):
                return item
        return None

    def resolve(self, item) -> Definition | None:
        """The declaration a Definition or Reference stands for."""
        if isinstance(item, Definition):
            return item
        if not isinstance(item, Reference):
            return None
        if item.owner is not None:
            return self._member(item)
        return self._innermost(item.name, item.scope, item.order, _ROLE_KINDS.get(item.role))

    def uses(self, definition: Definition) -> list:
        """Every Reference that resolves to a definition."""
        return [r for r in self.references if r.name and self.resolve(r) is definition]

    def named(self, kinds=None, scope: tuple = (), order: int | None = None) -> list:
        """The definitions visible in a scope (of the given kinds), innermost first, one per name."""
        seen, out = set(), []
        for definition in sorted(self.definitions, key=lambda d: -len(d.visible)):
            if kinds is not None and definition.kind not in kinds:
                continue
            if definition.visible != scope[:len(definition.visible)] or definition.name in seen:
                continue
            seen.add(definition.name)
            out.append(definition)
        return out

    def include_of(self, path: Path) -> Include | None:
        """The `include` in the root file through which `path` is read (directly or through other includes)."""
        chain = {i.target: i for i in self.includes}
        current = chain.get(path)
        while current is not None and current.span.path != self.root:
            current = chain.get(current.span.path)
        return current

    def _innermost(self, name: str, scope: tuple, order: int, kinds) -> Definition | None:
        best = None
        for definition in self.definitions:
            if kinds is not None and definition.kind not in kinds:
                continue
            if definition.visible != scope[:len(definition.visible)] or not definition.matches(name):
                continue
            if best is None or _closer(definition, best, order):
                best = definition
        return best

    def _member(self, reference: Reference) -> Definition | None:
        """`left.tip`: `tip` declared in the part that instance `left` uses."""
        instance = self.resolve(reference.owner)
        if instance is None or instance.kind != "instance":
            return None
        part = self._innermost(instance.part, instance.scope, instance.order, ("part",))
        if part is None:
            return None
        inside = [d for d in self.definitions if d.visible[-1:] == (id(part.tree),) and d.matches(reference.name)
                  and d.kind not in SCOPED_KINDS]
        return inside[0] if inside else None


# what each role of a reference may name
_ROLE_KINDS = {"call": ("kind",), "part": ("part",)}


def _closer(candidate: Definition, best: Definition, order: int) -> bool:
    """Of two declarations visible at a use: the one in the inner scope; in one scope, the last before the use
    (a `let` may be given again), else the first after it."""
    if len(candidate.visible) != len(best.visible):
        return len(candidate.visible) > len(best.visible)
    before, best_before = candidate.order < order, best.order < order
    if before != best_before:
        return before
    return candidate.order > best.order if before else candidate.order < best.order


_NAME_PIECES = re.compile(r"\{[^}]*\}")
# the names that are scoped (isaac_lang.lower_expr.Scope: values, kinds, parts); others belong to the scene
SCOPED_KINDS = ("let", "parameter", "loop variable", "kind", "part")


def template_pattern(name: str) -> re.Pattern:
    """`link{i+1}_tip` -> the names it makes: link0_tip, link12_tip, ... (the pieces are whole numbers)."""
    pieces = _NAME_PIECES.split(name)
    return re.compile(r"-?\d+".join(re.escape(p) for p in pieces))


def build_index(text: str, path: Path, read) -> SceneIndex:
    """Index the document `text` (at `path`) and every file it includes, read with `read(path) -> text | None`
    (None: it cannot be read; it is then left out)."""
    index = SceneIndex(root=path)
    _Walker(index, read).file(path, text, ())
    return index


class _Walker:
    """Walks parse trees in the expander's order, recording names, uses, properties and includes."""

    def __init__(self, index: SceneIndex, read):
        self.index = index
        self.read = read
        self.order = itertools.count()
        self.path = index.root
        self.lines: list = []

    def file(self, path: Path, text: str, scope: tuple) -> None:
        if path in self.index.files:
            return  # included twice, or a cycle: the front end says so
        self.index.files[path] = text
        tree = parse_text(text, path.name, Reporter())
        self.index.trees[path] = tree
        if tree is None:
            return
        outer_path, outer_lines = self.path, self.lines
        self.path, self.lines = path, text.split("\n")
        try:
            self.items(tree.children, scope)
        finally:
            self.path, self.lines = outer_path, outer_lines

    # -- items --------------------------------------------------------------------------------------------

    def items(self, items, scope: tuple) -> None:
        for item in items:
            if isinstance(item, Tree):
                handler = getattr(self, "_" + item.data, None)
                if handler is not None:
                    handler(item, scope)

    def _scene(self, item, scope):
        self.define("scene", item.children[0], scope, item)
        self.items(item.children[1:], scope)

    def _let_stmt(self, item, scope):
        name, value = item.children
        self.expression(value, scope)
        self.define("let", name, scope, item)

    def _include_stmt(self, item, scope):
        token = item.children[0]
        target = (self.path.parent / str(token)[1:-1]).resolve()
        self.index.includes.append(Include(target, self.span(token)))
        text = self.read(target)
        if text is not None:
            self.file(target, text, scope)

    def _kind_def(self, item, scope):
        self.define("kind", item.children[0], scope, item)
        inner = scope + (id(item),)
        for param in item.children[1:-1]:
            if param is not None:
                self.define("parameter", param, inner, item)
        self.expression(item.children[-1], inner)

    def _part_def(self, item, scope):
        self.define("part", item.children[0], scope, item)
        inner = scope + (id(item),)
        self.index.part_scopes.add(id(item))
        body = []
        for child in item.children[1:]:
            if isinstance(child, Tree) and child.data == "param":
                if child.children[1] is not None:
                    self.expression(child.children[1], inner)
                self.define("parameter", child.children[0], inner, child)
            elif child is not None:
                body.append(child)
        self.items(body, inner)

    def _use_part(self, item, scope):
        part, instance = item.children[:2]
        self.use(part, scope, "part")
        for arg in item.children[2:]:
            if isinstance(arg, Tree) and arg.data == "kwarg":
                self.expression(arg.children[1], scope)
            elif arg is not None:
                self.expression(arg, scope)
        definition = self.define("instance", instance, scope, item)
        if definition is not None:
            definition.part = str(part)

    def _for_loop(self, item, scope):
        variable, start, end = item.children[:3]
        self.expression(start, scope)
        self.expression(end, scope)
        inner = scope + (id(item),)
        self.define("loop variable", variable, inner, item)
        self.items(item.children[3:], inner)

    def _setting(self, item, scope):
        key, value = item.children
        self.property(key, value, vocabulary.SETTINGS, scope)

    def _solver(self, item, scope):
        if len(item.children) > 1 and item.children[1] is not None:
            self.block(item.children[1], vocabulary.SOLVER_PROPS, scope)

    def _exclude(self, item, scope):
        for child in item.children:
            self.expression(child, scope)

    _collide = _exclude

    def _declaration(self, item, scope):
        """`KEYWORD NAME ... [{ properties }]`: a material, a constraint, a force, a wind, a sound, a camera, a
        light."""
        table = DECLARATION_TABLES[item.data]
        self.define(item.data, item.children[0], scope, item)
        for child in item.children[1:]:
            if isinstance(child, Tree) and child.data == "block":
                self.block(child, table, scope)
            elif isinstance(child, Tree):
                self.expression(child, scope)

    _material = _constraint = _force = _wind = _sound = _camera = _light = _declaration

    def _body(self, item, scope):
        self.define("body", item.children[0], scope, item)
        self.body_block(item.children[-1], scope + (id(item),), vocabulary.BODY_PROPS)

    def body_block(self, block, scope, table):
        """A body's block: its properties, and the parts, loops and lets of a compound body."""
        for child in block.children:
            if child.data == "prop":
                self.property(child.children[0], child.children[1], table, scope)
            elif child.data == "let_stmt":
                self._let_stmt(child, scope)
            elif child.data == "body_part":
                self.define("piece", child.children[0], scope, child)
                self.body_block(child.children[-1], scope, vocabulary.PART_PROPS)
            elif child.data == "part_loop":
                variable, start, end = child.children[:3]
                self.expression(start, scope)
                self.expression(end, scope)
                inner = scope + (id(child),)
                self.define("loop variable", variable, inner, child)
                self.body_block(Tree("block", child.children[3:]), inner, table)

    # -- blocks and expressions ---------------------------------------------------------------------------

    def block(self, block, table, scope):
        for prop in block.children:
            self.property(prop.children[0], prop.children[1], table, scope)

    def property(self, key, value, table, scope):
        token = key.children[0] if isinstance(key, Tree) else key
        self.index.properties.append(PropertyKey(str(token), self.span(token), table, value))
        if isinstance(value, Tree) and value.data == "block":
            self.block(value, NESTED_TABLES.get(str(token), {}), scope)
        else:
            self.expression(value, scope)

    def expression(self, tree, scope) -> None:
        """Record every name an expression uses (iteratively: expressions may be long chains)."""
        stack = [tree]
        while stack:
            node = stack.pop()
            if not isinstance(node, Tree):
                continue
            if node.data == "name_ref":
                self.name_ref(node, scope)
            elif node.data == "call":
                self.use(node.children[0], scope, "call")
                stack.extend(node.children[1:])
            elif node.data == "kwarg":
                stack.append(node.children[1])
            elif node.data == "keys":
                stack.extend(c for c in node.children if isinstance(c, Tree))
            else:
                stack.extend(node.children)

    def name_ref(self, node, scope):
        owner = None
        for token in node.children:
            reference = self.use(token, scope, "value")
            if reference is not None and owner is not None:
                reference.owner = owner
            owner = reference

    # -- records ------------------------------------------------------------------------------------------

    def define(self, kind: str, name_tree, scope: tuple, tree: Tree) -> Definition | None:
        token = name_tree.children[0] if isinstance(name_tree, Tree) else name_tree
        if not isinstance(token, Token):
            return None
        span = self.span(token)
        definition = Definition(kind, str(token), span, scope, next(self.order), tree,
                                header=self.lines[span.line - 1].strip() if span.line <= len(self.lines) else "",
                                extent=(span.line, _last_line(tree, span.line)), visible=self.visible(kind, scope))
        self.index.definitions.append(definition)
        return definition

    def visible(self, kind: str, scope: tuple) -> tuple:
        if kind in SCOPED_KINDS:
            return scope
        parts = [k for k, scope_id in enumerate(scope) if scope_id in self.index.part_scopes]
        return scope[:parts[-1] + 1] if parts else ()

    def use(self, token, scope: tuple, role: str) -> Reference | None:
        if not isinstance(token, Token):
            return None
        reference = Reference(str(token), self.span(token), scope, next(self.order), role)
        self.index.references.append(reference)
        return reference

    def span(self, token: Token) -> Span:
        return Span(self.path, token.line, token.column, token.column + len(token))


def _last_line(tree: Tree, first: int) -> int:
    """The last line a declaration's tokens reach (its closing `}` is not a token: the caller looks past it)."""
    last = first
    for token in tree.scan_values(lambda v: isinstance(v, Token)):
        if token.end_line is not None and token.end_line > last:
            last = token.end_line
    return last
