"""Lowering of constraints (the library, `+` and `-` combination, named kinds), forces and sound triggers.

A constraint expression is an algebra over rows (docs/design/physics.md section 3): `a + b` is the union of the rows of
a and b; `a - tz` removes the element row `tz` from a. A named kind (`kind windmill(a, b) = ...`) is expanded
at each use with its parameters bound.
"""
from __future__ import annotations

import dataclasses

import math

import numpy as np
from lark import Token, Tree

from isaac_ir import expr as E
from isaac_ir import ir
from isaac_ir import units as U
from isaac_ir.diagnostics import did_you_mean
from isaac_lang.lower_expr import AXES, CONTEXTS, FIXED, BodyRef, ExprContext, Scope, Typed, range_ends, ref_name, ref_text
from isaac_lang.props import Props
from isaac_lang.vocabulary import CONSTRAINT_PROPS, FORCE_PROPS

ELEMENTS = {"tx": ("x", False), "ty": ("y", False), "tz": ("z", False),
            "rx": ("x", True), "ry": ("y", True), "rz": ("z", True)}
POINT_ROWS = ("tx", "ty", "tz")
LIBRARY = ("nail", "point", "orient", "plane", "gear", "rope", "weld") + tuple(ELEMENTS)


def lengths_over_first_minute(node):
    """(t, |v(t)|) of a vector expression of t every 0.25 s over the first minute: where a direction that follows
    t is checked (to stay of length 1 in a row, not to pass through zero in a wind)."""
    for t in np.linspace(0.0, 60.0, 241):
        yield float(t), float(np.linalg.norm(E.evaluate(node, {"t": float(t)})))


class ConstraintLowerer:
    def __init__(self, scene):
        self.scene = scene  # the SceneLowerer: bodies, name resolution

    # -- declarations -------------------------------------------------------------------------------------

    def constraint(self, decl) -> ir.Constraint:
        expr_tree = decl.tree.children[1]
        window, block = None, None
        for child in decl.tree.children[2:]:
            if isinstance(child, Tree) and child.data == "block":
                block = child
            elif child is not None:
                window = child
        terms = self.terms(expr_tree, decl.scope, decl)
        start, end = self.window(window, decl)
        props = Props(block, CONSTRAINT_PROPS, f"constraint `{decl.name}`", decl.lowerer, decl.scope)
        frequency = props.scalar("stabilize", U.FREQUENCY)
        if frequency is not None and frequency <= 0:
            raise decl.lowerer.fail("the stabilization frequency must be positive", props.node("stabilize"))
        self._check_not_static(terms, decl)
        return ir.Constraint(decl.name, tuple(terms), start, end, frequency,
                             props.scalar("damping", U.DIMENSIONLESS), props.scalar("compliance", U.DIMENSIONLESS),
                             str(decl.lowerer.pos(decl.tree)))

    def window(self, window, decl, what: str = "constraint"):
        """(start, end) of `during A .. B`, `from A`, `until B` (or always: 0 .. inf)."""
        if window is None:
            return 0.0, math.inf
        typed = (range_ends(decl.lowerer, window.children, decl.scope, FIXED) if window.data == "during"
                 else [decl.lowerer.lower(c, decl.scope, FIXED) for c in window.children])
        values = [decl.lowerer.constant(value, U.TIME, f"a {what}'s time", c)
                  for value, c in zip(typed, window.children)]
        if window.data == "during":
            start, end = values
            if end <= start:
                raise decl.lowerer.fail(f"the {what} ends before it starts", window,
                                        "write `during START .. END` with END after START")
            return start, end
        if window.data == "window_from":
            return values[0], math.inf
        return 0.0, values[0]

    def _check_not_static(self, terms, decl) -> None:
        for term in terms:
            movers = [b for b in term.bodies if self.scene.bodies[b].motion == "dynamic"]
            if not movers:
                names = " and ".join(f"`{b}`" for b in term.bodies) or "the world"
                raise decl.lowerer.fail(f"this {term.family} constraint joins {names}, none of which can move",
                                        decl.tree.children[1], "a constraint needs at least one dynamic body")

    # -- the algebra --------------------------------------------------------------------------------------

    def terms(self, tree, scope: Scope, decl) -> list:
        if isinstance(tree, Tree) and tree.data == "add":
            return self.terms(tree.children[0], scope, decl) + self.terms(tree.children[1], scope, decl)
        if isinstance(tree, Tree) and tree.data == "sub":
            return self._subtract(self.terms(tree.children[0], scope, decl), tree.children[1], decl)
        if isinstance(tree, Tree) and tree.data == "call":
            return self._call(tree, scope, decl)
        if isinstance(tree, Tree) and tree.data == "name_ref" and len(tree.children) == 1:
            kind = scope.lookup("kinds", str(tree.children[0]))
            if kind is not None:
                return self._kind(kind, [], tree, decl)
        raise decl.lowerer.fail("expected a constraint such as nail(...), point(...), orient(...)", tree,
                                "constraints combine with `+` and lose element rows with `-`")

    def _subtract(self, terms, tree, decl) -> list:
        name = str(tree.children[0]) if isinstance(tree, Tree) and tree.data in ("name_ref", "call") else None
        if name not in ELEMENTS:
            raise decl.lowerer.fail("only an element row (tx ty tz rx ry rz) can be subtracted", tree)
        out, removed = [], False
        for term in terms:
            if name in term.rows:
                removed = True
                rows = tuple(r for r in term.rows if r != name)
                if rows:
                    out.append(ir.ConstraintTerm(term.family, term.bodies, term.params, rows))
            else:
                out.append(term)
        if not removed:
            raise decl.lowerer.fail(f"nothing to subtract: no `{name}` row on the left", tree,
                                    "point and nail rows are tx, ty, tz; weld rows are tx ... rz")
        return out

    def _call(self, tree, scope, decl) -> list:
        fn = str(tree.children[0])
        args = [c for c in tree.children[1:] if c is not None]
        kind = scope.lookup("kinds", fn)
        if kind is not None:
            return self._kind(kind, args, tree, decl, scope)
        if fn in ELEMENTS:
            return self._element(fn, args, tree, scope, decl)
        builder = getattr(self, "_lib_" + fn, None) if fn in LIBRARY else None
        if builder is None:
            raise decl.lowerer.fail(f"unknown constraint `{fn}`", tree.children[0],
                                    did_you_mean(fn, LIBRARY + tuple(scope.visible("kinds"))))
        return builder(args, tree, scope, decl)

    def _kind(self, kind, args, tree, decl, scope=None) -> list:
        params, body, kind_scope, kind_lowerer = kind
        if len(args) != len(params):
            raise decl.lowerer.fail(f"`{tree.children[0]}` takes {len(params)} argument(s), got {len(args)}", tree)
        inner = Scope(parent=kind_scope, prefix=(scope or decl.scope).prefix)
        for name, arg in zip(params, args):
            inner.values[name] = self._kind_argument(arg, scope or decl.scope, decl)

        return self.terms(body, inner, dataclasses.replace(decl, scope=inner, lowerer=kind_lowerer))

    def _kind_argument(self, arg, scope, decl):
        if isinstance(arg, Tree) and arg.data == "name_ref":
            name = ref_name(arg, scope, decl.lowerer)
            bound = scope.lookup("values", name) if len(arg.children) == 1 else None
            if isinstance(bound, (BodyRef, Typed)):
                return bound
            return BodyRef(self.scene.resolve_body_name(name, arg, scope, decl.lowerer), decl.lowerer.pos(arg))
        return decl.lowerer.lower(arg, scope, ExprContext())

    # -- argument readers ---------------------------------------------------------------------------------

    def body(self, tree, scope, decl) -> str:
        if isinstance(tree, Tree) and tree.data == "name_ref":
            return self.scene.resolve_body_name(ref_name(tree, scope, decl.lowerer), tree, scope, decl.lowerer)
        raise decl.lowerer.fail("expected a body name", tree)

    def anchor(self, tree, scope, decl, what="a body point `body @ (x, y, z)`"):
        """(body, body-frame point) from `body @ p`, `body @ world p`, or a bare body (its centre)."""
        if isinstance(tree, Tree) and tree.data in ("anchor", "world_anchor"):
            body = self.body(tree.children[0], scope, decl)
            value = decl.lowerer.lower(tree.children[1], scope, FIXED)
            point = np.array(decl.lowerer.constant(value, U.LENGTH, "a body point", tree.children[1], size=3))
            if tree.data == "world_anchor":
                x0, R0 = self.pose(body)
                point = R0.T @ (point - x0)
            else:  # measured from the body's origin (a compound's or a mesh's need not be its centre of mass)
                point = point + np.asarray(self.scene.bodies[body].shape.offset, float)
            return body, tuple(float(v) for v in point)
        if isinstance(tree, Tree) and tree.data == "name_ref":
            return self.body(tree, scope, decl), (0.0, 0.0, 0.0)
        raise decl.lowerer.fail(f"expected {what}", tree)

    def vector(self, tree, scope, decl, dim, what, time=False):
        value = decl.lowerer.lower(tree, scope, CONTEXTS[time, False])
        node = decl.lowerer.coerce(value, dim, what, tree, size=3)
        return node if time else tuple(node.value)

    def moving_vector(self, tree, scope, decl, dim, what):
        """A world vector that may be a function of time: a tuple when it is not, else its expression."""
        node = self.vector(tree, scope, decl, dim, what, time=True)
        return tuple(float(v) for v in node.value) if isinstance(node, E.Const) else node

    def scalar(self, tree, scope, decl, dim, what, time=False):
        value = decl.lowerer.lower(tree, scope, CONTEXTS[time, False])
        if not time:
            return decl.lowerer.constant(value, dim, what, tree)
        node = decl.lowerer.coerce(value, dim, what, tree)
        return float(node.value) if isinstance(node, E.Const) else node

    def _unit_of_time(self, node, tree, decl):
        """A world direction of time must stay a unit vector (checked over the first minute)."""
        for t, length in lengths_over_first_minute(node):
            if abs(length - 1.0) > 1e-9:
                raise decl.lowerer.fail(f"a direction that changes over time must stay of length 1 (it is "
                                        f"{length:.6g} at t = {t:g} s)", tree,
                                        "e.g. `(cos(w * t), sin(w * t), 0)`")
        return node

    def direction(self, tree, scope, decl, time=False):
        """(body or None, unit vector in that body's frame): `a.x`, `-a.y`, `x`, `(0, 0, 1)`, a vector let; with
        `time`, a world direction may be a function of time (its expression, checked to stay of length 1)."""
        sign = 1.0
        while isinstance(tree, Tree) and tree.data == "neg":
            sign, tree = -sign, tree.children[0]
        if isinstance(tree, Tree) and tree.data == "name_ref":
            parts = [ref_text(tree.children[0], scope, decl.lowerer)] + [str(t) for t in tree.children[1:]]
            if len(parts) == 1 and parts[0] in AXES and scope.lookup("values", parts[0]) is None:
                return None, tuple(sign * v for v in AXES[parts[0]])
            if len(parts) >= 2:
                # `wheel.x`, or a part instance's body `left.wheel.x`
                if parts[-1] not in AXES:
                    raise decl.lowerer.fail(f"`{parts[-1]}` is not an axis", tree, "body axes are x, y and z")
                body = self.scene.resolve_body_name(".".join(parts[:-1]), tree, scope, decl.lowerer)
                return body, tuple(sign * v for v in AXES[parts[-1]])
        if time:
            moving = self.moving_vector(tree, scope, decl, U.DIMENSIONLESS, "a direction")
            if not isinstance(moving, tuple):
                return None, self._unit_of_time(E.mul(moving, E.Const(sign)), tree, decl)
        vec = np.array(self.vector(tree, scope, decl, U.DIMENSIONLESS, "a direction")) * sign
        norm = np.linalg.norm(vec)
        if norm == 0:
            raise decl.lowerer.fail("a direction must not be the zero vector", tree)
        return None, tuple(float(v) for v in vec / norm)

    def pose(self, body: str):
        """Position and rotation matrix of a body at the start (for `@ world` points and default targets)."""
        from isaac_ir import expr as X

        spec = self.scene.bodies[body]
        x0 = np.asarray(X.evaluate(spec.position, {"t": 0.0}), dtype=float)
        q = np.asarray(X.evaluate(spec.orientation, {"t": 0.0}), dtype=float)
        w, x, y, z = q / np.linalg.norm(q)
        R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                      [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                      [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        return x0, R

    def _arity(self, args, counts, tree, decl, usage):
        if len(args) not in counts:
            raise decl.lowerer.fail(f"`{tree.children[0]}` takes {usage}", tree)

    # -- the library (docs/design/physics.md section 3) ---------------------------------------------------------------

    def _lib_nail(self, args, tree, scope, decl):
        self._arity(args, (1, 2), tree, decl, "(body @ point) or (body @ point, world point)")
        body, point = self.anchor(args[0], scope, decl)
        if len(args) == 2:
            target = self.vector(args[1], scope, decl, U.LENGTH, "the nail's position", time=True)
        else:
            x0, R0 = self.pose(body)
            target = E.Const(tuple(float(v) for v in x0 + R0 @ np.array(point)))
        return [_term("nail", (body,), {"point": point, "target": target}, POINT_ROWS)]

    def _lib_point(self, args, tree, scope, decl):
        self._arity(args, (2,), tree, decl, "(a @ point, b @ point)")
        body_a, point_a = self.anchor(args[0], scope, decl)
        body_b, point_b = self.anchor(args[1], scope, decl, "a second body point (for a world point use nail)")
        if body_a == body_b:
            raise decl.lowerer.fail("a point-to-point constraint joins two different bodies", tree)
        return [_term("point", (body_a, body_b), {"point_a": point_a, "point_b": point_b}, POINT_ROWS)]

    def _lib_orient(self, args, tree, scope, decl):
        if len(args) == 2:
            body_a, axis_a = self.direction(args[0], scope, decl)
            body_b, axis_b = self.direction(args[1], scope, decl, time=True)
        elif len(args) in (3, 4):
            body_a = self.body(args[0], scope, decl)
            _, axis_a = self.direction(args[1], scope, decl)
            body_b = self.body(args[2], scope, decl) if len(args) == 4 else None
            _, axis_b = self.direction(args[-1], scope, decl, time=body_b is None)
        else:
            raise decl.lowerer.fail("`orient` takes (a.axis, direction), (a.axis, b.axis), (a, T, N) or "
                                    "(a, T, b, N)", tree)
        if body_a is None:
            raise decl.lowerer.fail("the first direction must belong to a body, e.g. `wheel.x`", args[0])
        bodies = (body_a,) if body_b is None else (body_a, body_b)
        return [_term("orient", bodies, {"axis_a": axis_a, "axis_b": axis_b}, ("orient",))]

    def _lib_plane(self, args, tree, scope, decl):
        self._arity(args, (3,), tree, decl, "(a @ point, plane point, normal)")
        body_a, point_a = self.anchor(args[0], scope, decl)
        body_b = None
        if isinstance(args[1], Tree) and args[1].data in ("anchor", "world_anchor"):
            body_b, plane_point = self.anchor(args[1], scope, decl)
        else:
            plane_point = self.moving_vector(args[1], scope, decl, U.LENGTH, "the plane's point")
        normal_body, normal = self.direction(args[2], scope, decl, time=body_b is None)
        if normal_body is not None and normal_body != body_b:
            raise decl.lowerer.fail("the normal must belong to the same body as the plane's point", args[2])
        bodies = (body_a,) if body_b is None else (body_a, body_b)
        return [_term("plane", bodies, {"point_a": point_a, "plane_point": plane_point, "normal": normal},
                      ("plane",))]

    def _lib_gear(self, args, tree, scope, decl):
        self._arity(args, (4,), tree, decl, "(a, radius a, b, radius b): a.z and b.z are the default axes")
        gears = []
        for body_tree, radius_tree in ((args[0], args[1]), (args[2], args[3])):
            body, axis = self._gear_axis(body_tree, scope, decl)
            radius = self.scalar(radius_tree, scope, decl, U.LENGTH, "a gear radius", time=True)
            if not isinstance(radius, float):  # a radius of time: positive over the first minute
                lowest = min(float(E.evaluate(radius, {"t": float(t)})) for t in np.linspace(0.0, 60.0, 241))
                if lowest <= 0:
                    raise decl.lowerer.fail("a gear radius must stay positive", radius_tree)
            elif radius <= 0:
                raise decl.lowerer.fail("a gear radius must be positive", radius_tree)
            gears.append((body, axis, radius))
        (a, axis_a, ra), (b, axis_b, rb) = gears
        return [_term("gear", (a, b), {"axis_a": axis_a, "radius_a": ra, "axis_b": axis_b, "radius_b": rb},
                      ("gear",))]

    def _gear_axis(self, tree, scope, decl):
        if isinstance(tree, Tree) and tree.data == "name_ref" and len(tree.children) >= 2 \
                and str(tree.children[-1]) in AXES:
            return self.direction(tree, scope, decl)
        return self.body(tree, scope, decl), (0.0, 0.0, 1.0)

    def _lib_rope(self, args, tree, scope, decl):
        self._arity(args, (4,), tree, decl, "(gear, arm to the rim, weight, rope direction)")
        gear = self.body(args[0], scope, decl)
        arm = self.vector(args[1], scope, decl, U.LENGTH, "the arm from the gear's centre to the rope")
        weight = self.body(args[2], scope, decl)
        _, direction = self.direction(args[3], scope, decl)
        return [_term("rope", (gear, weight), {"arm": arm, "direction": direction}, ("rope",))]

    def _element(self, fn, args, tree, scope, decl):
        self._arity(args, (1, 2), tree, decl, "(a) or (a, b)")
        bodies = tuple(self.body(a, scope, decl) for a in args)
        axis, rotational = ELEMENTS[fn]
        return [_term("element", bodies, {"axis": AXES[axis], "rotational": rotational}, (fn,))]

    def _lib_weld(self, args, tree, scope, decl):
        return [t for fn in ELEMENTS for t in self._element(fn, args, tree, scope, decl)]

    # -- forces -------------------------------------------------------------------------------------------

    def force(self, decl) -> ir.Force:
        call = decl.tree.children[1]
        block = decl.tree.children[2] if len(decl.tree.children) > 2 else None
        if not (isinstance(call, Tree) and call.data == "call"):
            raise decl.lowerer.fail("expected spring(...), damper(...) or load(...)", call)
        kind = str(call.children[0])
        args = [c for c in call.children[1:] if c is not None]
        props = Props(block, FORCE_PROPS, f"force `{decl.name}`", decl.lowerer, decl.scope)
        if kind in ("spring", "damper"):
            return self._spring(kind, args, call, props, decl)
        if kind == "load":
            if len(args) != 1:
                raise decl.lowerer.fail("`load` takes one body (or body point)", call)
            body, point = self.anchor(args[0], decl.scope, decl)
            zero = E.Const((0.0, 0.0, 0.0))
            return ir.Force(decl.name, "load", (body,), (point,), 0.0, None, 0.0,
                            props.vector("force", U.FORCE, zero, time=True),
                            props.vector("torque", U.TORQUE, zero, time=True), str(decl.lowerer.pos(decl.tree)))
        raise decl.lowerer.fail(f"unknown force `{kind}`", call.children[0],
                                did_you_mean(kind, ("spring", "damper", "load")))

    def _spring(self, kind, args, call, props, decl) -> ir.Force:
        if len(args) != 2:
            raise decl.lowerer.fail(f"`{kind}` takes (a @ point, b @ point) or (a @ point, world point)", call)
        body_a, point_a = self.anchor(args[0], decl.scope, decl)
        if isinstance(args[1], Tree) and args[1].data in ("anchor", "world_anchor", "name_ref"):
            body_b, point_b = self.anchor(args[1], decl.scope, decl)
            bodies, points = (body_a, body_b), (point_a, point_b)
        else:
            # one body and a world point: `points` holds one more entry than `bodies`
            bodies, points = (body_a,), (point_a, self.vector(args[1], decl.scope, decl, U.LENGTH, "a world point"))
        stiffness = props.scalar("stiffness", U.STIFFNESS, 0.0)
        if kind == "spring" and not props.has("stiffness"):
            raise decl.lowerer.fail("a spring needs a `stiffness`", call, "e.g. `{ stiffness 100 N/m }`")
        zero = E.Const((0.0, 0.0, 0.0))
        return ir.Force(decl.name, kind, bodies, points, stiffness, props.scalar("rest", U.LENGTH),
                        props.scalar("damping", U.DAMPING, 0.0), zero, zero, str(decl.lowerer.pos(decl.tree)))

    # -- sound triggers -----------------------------------------------------------------------------------

    def trigger(self, tree, decl, winds: set):
        """(trigger, bodies, wind, time) of `collide(a, b)`, `contact(a, b)`, `wind(w)`, `at(time)`, `always`."""
        if isinstance(tree, Tree) and tree.data == "name_ref" and str(tree.children[0]) == "always":
            return "always", (), None, None
        if not (isinstance(tree, Tree) and tree.data == "call"):
            raise decl.lowerer.fail("expected collide(a, b), contact(a, b), wind(w), at(time) or always", tree)
        kind = str(tree.children[0])
        args = [c for c in tree.children[1:] if c is not None]
        if kind in ("collide", "contact"):
            bodies = tuple(self.body(a, decl.scope, decl) for a in args)
            if len(bodies) > 2:
                raise decl.lowerer.fail(f"`{kind}` names at most two bodies", tree)
            return kind, bodies, None, None
        if kind == "wind" and len(args) == 1:
            name = str(args[0].children[0]) if isinstance(args[0], Tree) else ""
            if name not in winds:
                raise decl.lowerer.fail(f"unknown wind `{name}`", args[0], did_you_mean(name, winds))
            return "wind", (), name, None
        if kind == "at" and len(args) == 1:
            return "time", (), None, self.scalar(args[0], decl.scope, decl, U.TIME, "a sound's time")
        raise decl.lowerer.fail(f"unknown trigger `{kind}`", tree.children[0],
                                did_you_mean(kind, ("collide", "contact", "wind", "at", "always")))


def _term(family: str, bodies: tuple, params: dict, rows: tuple) -> ir.ConstraintTerm:
    return ir.ConstraintTerm(family, bodies, tuple(sorted(params.items())), rows)
