"""The front end's driver: text -> parse tree -> expanded declarations -> IR -> checked IR.

    scene = load_scene("scenes/pendulum.isaac", overrides={"length": "2 m"})

Stops after the first stage that reports errors, with all of that stage's diagnostics (SceneError).
"""
from __future__ import annotations

import gc
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from lark.exceptions import UnexpectedInput

from isaac_ir import ir
from isaac_lang.assets import check_assets
from isaac_lang.check import check
from isaac_ir.diagnostics import Reporter, SceneError, SourceCache, SourcePos, did_you_mean
from isaac_lang.overrides import SET_POSITION, set_label, set_problem
from isaac_lang.expand import Expander, Limits
from isaac_lang.lower import SceneLowerer
from isaac_lang.lower_expr import ExprContext, ExprLowerer, Scope
from isaac_lang.syntax import describe_syntax_error, parse_expression
from isaac_lang.typos import explain_unit_typos


@dataclass
class Loaded:
    scene: ir.Scene
    warnings: list = field(default_factory=list)
    sources: SourceCache = None


def load_scene(path, overrides: dict | None = None, limits: Limits | None = None,
               sources: SourceCache | None = None, assets: bool = True) -> Loaded:
    """Parse, expand, lower and check the scene file at path (and read the files it names, unless `assets` is
    false). Raises SceneError with every diagnostic."""
    path = Path(path)
    return _load(path, path.parent, overrides or {}, limits or Limits(), sources or SourceCache(), assets=assets)


def load_text(text: str, name: str = "<scene>", overrides: dict | None = None, folder=".",
              limits: Limits | None = None, sources: SourceCache | None = None, assets: bool = True,
              texts: dict | None = None) -> Loaded:
    """The same for scene text held in memory (includes and assets resolve relative to `folder`); `texts` maps
    the real paths of included files to texts held in memory too (an editor's unsaved buffers)."""
    folder = Path(folder)
    path = folder / name
    return _load(path, folder, overrides or {}, limits or Limits(), sources or SourceCache(), text=text,
                 assets=assets, texts=texts)


@contextmanager
def _collector_paused():
    """Python's cyclic garbage collector paused while a scene loads (then resumed as it was).

    Loading allocates tens of thousands of small objects (tokens, trees, expressions) that live until the IR is
    built; the collector, run every few hundred allocations, walks them again and again: a quarter of the
    time of a large scene. Reference counting frees everything as usual; cycles, if any, wait for the next run.
    """
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _load(path: Path, root: Path, overrides: dict, limits: Limits, sources: SourceCache, text=None,
          assets: bool = True, texts: dict | None = None) -> Loaded:
    with _collector_paused():
        try:
            return _load_stages(path, root, overrides, limits, sources, text, assets, texts)
        except SceneError as error:
            explained = explain_unit_typos(error, sources)
            explained.sources = sources
            raise explained from None


def _load_stages(path: Path, root: Path, overrides: dict, limits: Limits, sources: SourceCache,
                 text=None, assets: bool = True, texts: dict | None = None) -> Loaded:
    reporter = Reporter()
    parsed_overrides = _parse_overrides(overrides, reporter, sources)
    reporter.raise_if_any()
    expander = Expander(root, sources, reporter, parsed_overrides, limits, texts)
    expander.override_texts = {name: str(text).strip() for name, text in overrides.items()}
    scope = Scope()
    if text is None:
        expander.expand_file(path, scope)
    else:
        _expand_text(expander, path, text, scope)
    for name in sorted(set(parsed_overrides) - expander.out.used_overrides):
        reporter.error(f"`{set_label(name, str(overrides[name]).strip())}`: the scene has no parameter `{name}`", None,
                       did_you_mean(name, expander.out.parameters) or
                       "parameters are the scene's top-level `let`s")
    reporter.raise_if_any()
    root_name = expander.include_stack[0] if expander.include_stack else path.name
    scene = SceneLowerer(expander.out, reporter, path.name).run()
    warnings = reporter.warnings + check(scene, reporter)
    reporter.raise_if_any()
    if assets:
        check_assets(scene, root, reporter, sources)
        reporter.raise_if_any()
    return Loaded(scene, warnings, sources)


def _expand_text(expander: Expander, path: Path, text: str, scope: Scope) -> None:
    from isaac_lang.syntax import parse_text

    name = path.name
    expander.sources.add(name, text)
    tree = parse_text(text, name, expander.reporter)
    if tree is not None:
        expander.include_stack.append(path.resolve())
        expander.items(tree.children, scope, ExprLowerer(name, expander.reporter), 0)
        expander.include_stack.pop()


def _parse_overrides(overrides: dict, reporter: Reporter, sources: SourceCache) -> dict:
    """--set NAME=VALUE: each VALUE is an expression of the language, e.g. `2 m` or `0.5*pi`."""
    parsed = {}
    for name, text in overrides.items():
        problem = set_problem(str(name), str(text).strip())
        if problem is not None:
            reporter.error(problem, SET_POSITION, "parameters are the scene's top-level `let`s: --set NAME=VALUE")
            continue
        label = set_label(name, str(text).strip())
        sources.add(label, str(text).strip())
        try:
            tree = parse_expression(str(text))
        except UnexpectedInput as error:
            message, pos, hint = describe_syntax_error(error, str(text), label)
            reporter.error(message, pos, hint)
            continue
        try:
            parsed[name] = ExprLowerer(label, reporter).lower(tree, Scope(), ExprContext())
        except SceneError:
            continue
    return parsed
