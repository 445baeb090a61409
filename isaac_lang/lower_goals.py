"""Lowering of `vary` and `goal` (docs/goals.md): the parameters a fit may change, and what the run must do.

    vary speed in 1 m/s .. 20 m/s
    goal hit: ball.position at 0.8 s = (2.5, 1.3, 0) m within 1 um
    goal land: first collide(ball, floor) at 0.45 s within 0.1 ms

Every goal is checked here to be one a finished run can answer: its body exists, its time lies within the
scene's, its value and tolerance are in the quantity's unit; a `vary` names a top-level `let` of one number, and
its bounds are in that let's unit.
"""
from __future__ import annotations

from lark import Token, Tree

from isaac_ir import expr as E
from isaac_ir import ir
from isaac_ir import units as U
from isaac_ir.diagnostics import SceneError, did_you_mean
from isaac_lang.lower_expr import FIXED, ref_name

# what a state goal may ask of a body, and the unit of each
QUANTITIES = {"position": U.LENGTH, "velocity": U.VELOCITY, "angle": U.ANGLE}
COMPONENTS = ("x", "y", "z")
EVENTS = ("collide", "contact")


class GoalLowerer:
    """Lowers the expansion's `vary` and `goal` statements, once every body is known (`scene` the SceneLowerer)."""

    def __init__(self, scene, timeline: ir.Timeline):
        self.scene = scene
        self.timeline = timeline

    def run(self) -> tuple:
        """(varies, goals), each a tuple in the order written; errors reported, the others still lowered."""
        varies, goals = [], []
        for tree, scope, lowerer in self.scene.x.goals:
            lower, out = (self.vary, varies) if tree.data == "vary" else (self.goal, goals)
            try:
                item = lower(tree, scope, lowerer)
            except SceneError:  # reported already; go on with the next
                continue
            self._unique(item, out, tree, lowerer)
            out.append(item)
        return tuple(varies), tuple(goals)

    def _unique(self, item, seen: list, tree, lowerer) -> None:
        for other in seen:
            if other.name == item.name:
                raise lowerer.fail(f"`{tree.data} {item.name}` is written twice", tree.children[0],
                                   f"the first is at {other.source}")

    # -- vary ---------------------------------------------------------------------------------------------

    def vary(self, tree: Tree, scope, lowerer) -> ir.Vary:
        name_token, low_tree, high_tree = tree.children
        name = str(name_token)
        let = self.scene.x.parameters.get(name)
        if let is None:
            raise lowerer.fail(f"`vary {name}`: the scene has no top-level `let {name}`", name_token,
                               did_you_mean(name, self.scene.x.parameters) or
                               f"`vary` frees a parameter: write `let {name} = VALUE` at the top of the scene first")
        if not isinstance(let.node, E.Const) or isinstance(let.node.value, (tuple, str)):
            raise lowerer.fail(f"`vary {name}`: `let {name}` is not one number", name_token,
                               "a fit varies single numbers (a speed, an angle, a friction)")
        dim = let.dim
        low, high = (self._bound(t, dim, name, scope, lowerer) for t in (low_tree, high_tree))
        if not low < high:
            raise lowerer.fail(f"`vary {name}`: the range is empty ({low:g} .. {high:g} in SI)", tree,
                               "write `vary NAME in LOW .. HIGH` with LOW below HIGH")
        return ir.Vary(name, low, high, float(let.node.value), dim or U.DIMENSIONLESS,
                       _written_unit(low_tree, high_tree, dim), str(lowerer.pos(tree)))

    def _bound(self, tree, dim, name: str, scope, lowerer) -> float:
        value = lowerer.lower(tree, scope, FIXED)
        if dim is None:  # the let is a plain number: so are its bounds
            if value.dim not in (None, U.DIMENSIONLESS):
                raise lowerer.fail(f"`vary {name}`: `let {name}` is a number without unit, but this bound is "
                                   f"{U.describe(value.dim)}", tree,
                                   f"give the let its unit (`let {name} = 5 {U.EXAMPLE_UNIT.get(value.dim, '')}`), "
                                   "or write the bounds without one")
            dim = U.DIMENSIONLESS
        return float(lowerer.constant(value, dim, f"the range of `vary {name}`", tree))

    # -- goal ---------------------------------------------------------------------------------------------

    def goal(self, tree: Tree, scope, lowerer) -> ir.Goal:
        name_token, body = tree.children
        name = str(name_token)
        if body.data == "state_goal":
            return self._state_goal(name, body, scope, lowerer, tree)
        return self._event_goal(name, body, scope, lowerer, tree)

    def _state_goal(self, name: str, tree: Tree, scope, lowerer, whole: Tree) -> ir.Goal:
        ref, at_word, time_tree, value_tree, within_word, tolerance_tree = tree.children
        self._word(at_word, "at", lowerer)
        self._word(within_word, "within", lowerer)
        body_name, quantity, component = self._quantity(ref, scope, lowerer)
        body = self.scene.resolve_body_name(body_name, ref, scope, lowerer)
        dim = QUANTITIES[quantity]
        size = 3 if quantity != "angle" and component is None else 0
        what = f"goal `{name}`"
        target = lowerer.constant(lowerer.lower(value_tree, scope, FIXED), dim, f"the value of {what}", value_tree,
                                  size)
        target = tuple(float(v) for v in target) if size else float(target)
        return ir.Goal(name, "state", (body,), quantity, component, self._time(time_tree, what, scope, lowerer),
                       target, self._tolerance(tolerance_tree, dim, what, scope, lowerer), str(lowerer.pos(whole)))

    def _event_goal(self, name: str, tree: Tree, scope, lowerer, whole: Tree) -> ir.Goal:
        event_tree, ref_a, ref_b, at_word, time_tree, within_word, tolerance_tree = tree.children
        event = str(event_tree.children[0])
        if event not in EVENTS:
            raise lowerer.fail(f"goal `{name}`: unknown event `{event}`", event_tree,
                               did_you_mean(event, EVENTS) or "a goal waits for the first `collide(a, b)` (an "
                                                              "impact) or `contact(a, b)` (a lasting contact)")
        self._word(at_word, "at", lowerer)
        self._word(within_word, "within", lowerer)
        a, b = (self.scene.resolve_body(ref, _Decl(scope, lowerer)) for ref in (ref_a, ref_b))
        if a == b:
            raise lowerer.fail(f"goal `{name}`: a body does not {event} with itself", ref_b)
        what = f"goal `{name}`"
        return ir.Goal(name, "event", (a, b), event, None, self._time(time_tree, what, scope, lowerer), None,
                       self._tolerance(tolerance_tree, U.TIME, what, scope, lowerer), str(lowerer.pos(whole)))

    def _quantity(self, ref: Tree, scope, lowerer) -> tuple:
        """`ball.position.x` -> ("ball", "position", "x"); a body inside a part keeps its dots (`left.bob`)."""
        words = ref_name(ref, scope, lowerer).split(".")
        component = words.pop() if len(words) > 2 and words[-1] in COMPONENTS else None
        if len(words) < 2 or words[-1] not in QUANTITIES:
            raise lowerer.fail(f"`{'.'.join(words)}` is not a quantity a goal can ask for", ref,
                               "write BODY.position, BODY.velocity or BODY.angle, or a component such as "
                               "BODY.position.x")
        return ".".join(words[:-1]), words[-1], component

    def _time(self, tree, what: str, scope, lowerer) -> float:
        time = float(lowerer.constant(lowerer.lower(tree, scope, FIXED), U.TIME, f"the time of {what}", tree))
        span = self.timeline
        if not span.start <= time <= span.end:
            raise lowerer.fail(f"the time of {what}, {time:g} s, is outside the scene's time ({span.start:g} s .. "
                               f"{span.end:g} s)", tree, "a goal is checked on the run: choose a time within "
                                                         "`time START .. END`, or run the scene longer")
        return time

    def _tolerance(self, tree, dim, what: str, scope, lowerer) -> float:
        tolerance = float(lowerer.constant(lowerer.lower(tree, scope, FIXED), dim, f"the tolerance of {what}", tree))
        if not tolerance > 0:
            raise lowerer.fail(f"the tolerance of {what} must be positive", tree,
                               "e.g. `within 1 mm`: how far from the value still meets the goal")
        return tolerance

    @staticmethod
    def _word(token: Token, expected: str, lowerer) -> None:
        if str(token) != expected:
            raise lowerer.fail(f"expected `{expected}`, got `{token}`", token,
                               "a goal reads `goal NAME: QUANTITY at TIME = VALUE within TOLERANCE`, or "
                               "`goal NAME: first collide(A, B) at TIME within TOLERANCE`")


class _Decl:
    """What SceneLowerer.resolve_body needs of a declaration: where the name was written."""

    def __init__(self, scope, lowerer):
        self.scope, self.lowerer = scope, lowerer


def _written_unit(low_tree, high_tree, dim) -> str:
    """The unit the range was written in (to print a fit's values in), else one of the quantity's own."""
    for tree in (low_tree, high_tree):
        if isinstance(tree, Tree) and tree.data == "quantity" and isinstance(tree.children[-1], Token):
            return str(tree.children[-1])
    if dim in (None, U.DIMENSIONLESS):
        return ""
    return "deg" if dim == U.ANGLE else U.EXAMPLE_UNIT.get(dim, U.format_dim(dim))
