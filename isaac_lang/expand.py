"""Stage 2a, expand: includes spliced, `let`s bound, parts instantiated, loops unrolled.

The result is a flat list of declarations, each with the scope it was written in, so that stage 2b (lower)
can resolve names once every body, material and wind is known, whatever the order they were written in.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from lark import Tree

from isaac_ir import expr as E
from isaac_ir import units as U
from isaac_ir.diagnostics import Reporter, SceneError, SourceCache, SourcePos, did_you_mean, display_path
from isaac_ir.files import BadEncoding, Confinement, FileRefused, real_path
from isaac_lang.lower_expr import CONTEXTS, FIXED, BodyRef, ExprContext, ExprLowerer, Scope, Typed, ref_name, interpolate_name
from isaac_lang.overrides import override_in_unit_written
from isaac_lang.syntax import parse_text

DECLARATIONS = ("material", "body", "constraint", "force", "wind", "sound", "camera", "light", "exclude",
                "collide")


@dataclass(frozen=True)
class Limits:
    """Bounds on expansion, so a runaway loop or part is a diagnostic and not a hang (raise with --max-items)."""

    max_items: int = 200_000  # declarations after expansion
    max_depth: int = 32  # nested includes and part instances
    max_seconds: float = 3.0  # wall-clock time for includes, loops and parts (--expand-seconds)
    include_path: tuple = ()  # folders outside the scene's own that its includes and assets may be read from


@dataclass
class Decl:
    """A declaration after expansion: its kind, its full name, the tree and the scope it was written in."""

    kind: str
    name: str | None
    tree: Tree
    scope: Scope
    lowerer: ExprLowerer  # knows the file the tree came from


@dataclass
class Expansion:
    decls: list = field(default_factory=list)
    settings: list = field(default_factory=list)  # (tree, scope, lowerer) of scene-level settings
    solvers: list = field(default_factory=list)
    scene_names: list = field(default_factory=list)  # (name, pos)
    parameters: dict = field(default_factory=dict)  # top-level lets after overrides: name -> Typed
    used_overrides: set = field(default_factory=set)
    # the scene's folder: the files it names are relative to it (lowering reads the meshes it validates and
    # integrates from there)
    folder: Path | None = None
    confinement: Confinement | None = None  # where those files may be read from (isaac_ir/files.py)
    goals: list = field(default_factory=list)  # (tree, scope, lowerer) of `vary` and `goal` (lower_goals.py)


class Expander:
    def __init__(self, root: Path, sources: SourceCache, reporter: Reporter, overrides: dict, limits: Limits,
                 texts: dict | None = None):
        self.root = root
        self.texts = texts or {}  # real path -> text held in memory (an editor's unsaved buffer), read instead
        self.sources = sources
        self.reporter = reporter
        self.overrides = overrides  # name -> Typed
        self.override_texts: dict = {}  # name -> the VALUE of `--set NAME=VALUE` as typed
        self.limits = limits
        self.out = Expansion(folder=root)
        self.include_stack: list[Path] = []
        self.confinement = Confinement.for_scene(root, limits.include_path)
        self.out.folder, self.out.confinement = Path(root), self.confinement
        self.trees: dict = {}  # real path -> parse tree (None: it could not be read or parsed): read once per load
        self.count = 0  # declarations so far
        self.expansions = 0  # loop iterations and part instances so far (a loop of lets counts too)
        self.halted = False  # a runaway was reported once; the expansion then stops quietly
        self.deadline = time.monotonic() + limits.max_seconds
        self.resolved: dict = {}  # path of an include -> its real path, or the FileRefused it raised
        self.names: dict = {}  # path -> its name in diagnostics

    # -- files --------------------------------------------------------------------------------------------

    def expand_file(self, path: Path, scope: Scope, depth: int = 0, at: SourcePos | None = None) -> None:
        resolved = self._resolve(path)
        if isinstance(resolved, FileRefused):  # a NUL byte in the name, a link to itself: nothing to open
            self.reporter.error(f"cannot read `{display_path(path, self.root)}`: {resolved.message}", at,
                                resolved.hint)
            return
        name = self._name(path)
        if resolved in self.include_stack:
            chain = " -> ".join(self._name(p) for p in self.include_stack + [resolved])
            self.halted = True  # a cycle never ends: the rest of the expansion would only repeat it
            self.reporter.error(f"include cycle: {chain}", at, "remove one of the includes")
            return
        if resolved not in self.trees:
            started = time.monotonic()
            self.trees[resolved] = self._read_and_parse(path, name, at)
            self.deadline += time.monotonic() - started  # the budget is for expansion: a long file's parse is not
        tree = self.trees[resolved]
        if tree is None:
            return
        self.include_stack.append(resolved)
        try:
            self.items(tree.children, scope, ExprLowerer(name, self.reporter), depth)
        finally:
            self.include_stack.pop()

    def _resolve(self, path: Path):
        """The real path of a file to include, or the FileRefused that says why it has none; worked out once
        per name (an include inside a loop names the same file each time)."""
        if path not in self.resolved:
            try:
                self.resolved[path] = real_path(path)
            except FileRefused as error:
                self.resolved[path] = error
        return self.resolved[path]

    def _name(self, path: Path) -> str:
        if path not in self.names:
            self.names[path] = display_path(path, self.root)
        return self.names[path]

    def _read_and_parse(self, path: Path, name: str, at: SourcePos | None):
        """The parse tree of a scene file, or None with the reason reported (at the include that names it, or at
        the bad byte of a file that is not UTF-8). A refused file is never opened (isaac_ir/files.py)."""
        try:
            text = self._read_text(path)
        except BadEncoding as error:
            self.sources.add(name, error.text)
            self.reporter.error(f"`{name}`: {error.message}", SourcePos(name, error.line, error.col), error.hint)
            return None
        except FileRefused as error:
            self.reporter.error(f"cannot read `{name}`: {error.message}", at,
                                error.hint or "paths in `include` are relative to the including file")
            return None
        self.sources.add(name, text)
        return parse_text(text, name, self.reporter)

    def _read_text(self, path: Path) -> str:
        """The text of a scene file: the copy held in memory when there is one, else the file's (both only where
        the scene may read)."""
        if self.texts:
            held = self.texts.get(self.confinement.allowed(path))
            if held is not None:
                return held
        return self.confinement.read_text(path)

    # -- items --------------------------------------------------------------------------------------------

    def items(self, items, scope: Scope, lowerer: ExprLowerer, depth: int, top: bool = True) -> None:
        for item in items:
            if self.halted:
                return  # a runaway was reported: what is left would only repeat it
            try:
                self._check_time(item, lowerer)
                self.item(item, scope, lowerer, depth, top)
            except SceneError:
                # recorded already; go on with the next item so one run reports several errors
                if len(self.reporter.diagnostics) >= Reporter.LIMIT:
                    raise

    def item(self, item: Tree, scope: Scope, lowerer: ExprLowerer, depth: int, top: bool) -> None:
        kind = item.data
        if kind == "scene":
            self._scene(item, scope, lowerer, depth)
        elif kind == "let_stmt":
            self._let(item, scope, lowerer, top)
        elif kind == "include_stmt":
            self._include(item, scope, lowerer, depth)
        elif kind == "kind_def":
            self._kind(item, scope, lowerer)
        elif kind == "part_def":
            scope.parts[str(item.children[0])] = (item, lowerer)
        elif kind == "use_part":
            self._use(item, scope, lowerer, depth)
        elif kind == "for_loop":
            self._for(item, scope, lowerer, depth)
        elif kind == "setting":
            if scope.prefix:
                raise lowerer.fail("scene settings belong to the scene, not inside a part", item)
            self.out.settings.append((item, scope, lowerer))
        elif kind == "solver":
            self.out.solvers.append((item, scope, lowerer))
        elif kind in ("vary", "goal"):
            if scope.prefix:
                raise lowerer.fail(f"`{kind}` belongs to the scene, not inside a part", item)
            self.out.goals.append((item, scope, lowerer))
        elif kind in DECLARATIONS:
            self._declaration(kind, item, scope, lowerer)
        else:  # pragma: no cover - the grammar has no other items
            raise lowerer.fail(f"unexpected `{kind}`", item)

    def _scene(self, item, scope, lowerer, depth):
        name = self.decl_name(item.children[0], scope, lowerer)
        self.out.scene_names.append((name, lowerer.pos(item.children[0])))
        self.items(item.children[1:], scope, lowerer, depth, top=True)

    def _let(self, item, scope, lowerer, top):
        name_token, value_tree = item.children
        name = str(name_token)
        if top and not scope.prefix and name in self.overrides:
            self.out.used_overrides.add(name)
            written = lowerer.lower(value_tree, scope, CONTEXTS[True, True])
            value = override_in_unit_written(name, self.overrides[name], written, value_tree, lowerer,
                                             self.override_texts.get(name, ""), self.reporter)
        else:
            value = lowerer.lower(value_tree, scope, CONTEXTS[True, True])
        scope.values[name] = value
        if top and not scope.prefix:
            self.out.parameters[name] = value

    def _include(self, item, scope, lowerer, depth):
        if not self._spend(1, 0, item, lowerer):
            return
        if depth >= self.limits.max_depth:
            self.halted = True
            raise lowerer.fail("includes nested too deeply", item, "is there an include cycle?")
        relative = str(item.children[0])[1:-1]
        here = self.include_stack[-1].parent if self.include_stack else self.root
        self.expand_file(here / relative, scope, depth + 1, lowerer.pos(item.children[0]))

    def _kind(self, item, scope, lowerer):
        name = str(item.children[0])
        params = [str(t) for t in item.children[1:-1] if t is not None]
        scope.kinds[name] = (params, item.children[-1], scope, lowerer)

    def _use(self, item, scope: Scope, lowerer: ExprLowerer, depth: int):
        part_name = str(item.children[0])
        found = scope.lookup("parts", part_name)
        if found is None:
            raise lowerer.fail(f"unknown part `{part_name}`", item.children[0],
                               did_you_mean(part_name, scope.visible("parts")) or "declare it with `part NAME(...) { ... }`")
        if depth >= self.limits.max_depth:
            self.halted = True
            raise lowerer.fail("parts nested too deeply", item, "does a part use itself?")
        if not self._spend(1, 0, item, lowerer):
            return
        part_tree, part_lowerer = found
        instance = self.decl_name(item.children[1], scope, lowerer)
        inner = Scope(parent=scope, prefix=scope.prefix + instance + ".")
        self._bind_part_params(part_tree, item, inner, scope, lowerer, part_lowerer)
        body = [c for c in part_tree.children[1:] if isinstance(c, Tree) and c.data != "param"]
        self.items(body, inner, part_lowerer, depth + 1, top=False)

    def _bind_part_params(self, part_tree, use_tree, inner, scope, lowerer, part_lowerer):
        params = {str(p.children[0]): p for p in part_tree.children[1:] if isinstance(p, Tree) and p.data == "param"}
        given = {}
        for arg in use_tree.children[2:]:
            if arg is None:
                continue
            if not (isinstance(arg, Tree) and arg.data == "kwarg"):
                raise lowerer.fail("part arguments are named: `use part instance(name = value)`", arg)
            key = str(arg.children[0])
            if key not in params:
                raise lowerer.fail(f"part `{part_tree.children[0]}` has no parameter `{key}`", arg.children[0],
                                   did_you_mean(key, params))
            given[key] = self._part_argument(arg.children[1], scope, lowerer)
        for key, param in params.items():
            if key in given:
                inner.values[key] = given[key]
            elif param.children[1] is not None:
                inner.values[key] = part_lowerer.lower(param.children[1], inner, ExprContext())
            else:
                raise lowerer.fail(f"part `{part_tree.children[0]}` needs a value for `{key}`", use_tree)

    def _part_argument(self, tree, scope, lowerer):
        """A part argument is a value, or a body name (then the part can attach to that body)."""
        if isinstance(tree, Tree) and tree.data == "name_ref":
            name = ref_name(tree, scope, lowerer)  # `beam`, `link{i}`, `upper.bob`
            bound = scope.lookup("values", name) if len(tree.children) == 1 else None
            if isinstance(bound, BodyRef):
                return bound
            if bound is None and name not in E.CONSTANTS and name != "t":
                # resolved against the bodies once all are known, from the caller's scope outward
                return BodyRef(name, lowerer.pos(tree), tuple(scope.prefixes()))
        return lowerer.lower(tree, scope, ExprContext())

    def _for(self, item, scope, lowerer, depth):
        var, start_tree, end_tree = item.children[:3]
        start = self._integer(start_tree, scope, lowerer)
        end = self._integer(end_tree, scope, lowerer)
        body = item.children[3:]
        if not self._spend(max(0, end - start), len(body), item, lowerer):
            return
        for i in range(start, end):
            inner = scope.child()
            inner.values[str(var)] = Typed(E.Const(float(i)), None)
            self.items(body, inner, lowerer, depth, top=False)

    def _spend(self, times: int, size: int, item, lowerer) -> bool:
        """Account for `times` expansions of `size` items; False (quietly) once the limit was reported."""
        if self.halted:
            return False  # a runaway was reported already
        self.expansions += times
        if times * max(1, size) + self.count > self.limits.max_items or self.expansions > self.limits.max_items:
            self.halted = True
            raise lowerer.fail(f"this expands the scene beyond the limit of {self.limits.max_items} declarations",
                               item, "raise the limit with --max-items if you mean it")
        return True

    def _check_time(self, item, lowerer) -> None:
        """Stop, at the item being expanded, once expansion has taken longer than its budget: counted as the
        work is done, so a loop of includes that fail stops early rather than after its last iteration."""
        if time.monotonic() > self.deadline:
            self.halted = True
            raise lowerer.fail(f"expanding the scene's includes, loops and parts took more than "
                               f"{self.limits.max_seconds:g} s; stopped here", item,
                               "a loop of includes or parts asks for more than it seems; raise the limit with "
                               "--expand-seconds if you mean it")

    def _integer(self, tree, scope, lowerer) -> int:
        value = lowerer.lower(tree, scope, FIXED)
        if not isinstance(value.node, E.Const) or isinstance(value.node.value, tuple) \
                or value.dim not in (None, U.DIMENSIONLESS) or value.node.value != int(value.node.value):
            raise lowerer.fail("a loop bound must be a whole number", tree)
        return int(value.node.value)

    def _declaration(self, kind, item, scope, lowerer):
        if self.halted:
            return
        self.count += 1
        if self.count > self.limits.max_items:
            self.halted = True
            raise lowerer.fail(f"the scene expands to more than {self.limits.max_items} declarations", item,
                               "raise the limit with --max-items if you mean it")
        name = None
        if kind not in ("exclude", "collide"):
            name = scope.prefix + self.decl_name(item.children[0], scope, lowerer)
        self.out.decls.append(Decl(kind, name, item, scope, lowerer))

    # -- names --------------------------------------------------------------------------------------------

    def decl_name(self, tree, scope: Scope, lowerer: ExprLowerer) -> str:
        token = tree.children[0] if isinstance(tree, Tree) else tree
        text = str(token)
        if token.type != "TNAME":
            return text
        return interpolate_name(text, token, scope, lowerer)


