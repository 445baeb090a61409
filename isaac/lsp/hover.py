"""What a hover says (Markdown): a `let`'s declaration and value in SI units, a body's shape, mass and inertia, a
material's coefficients, any other declaration's first line, a property's meaning (the checker's own tables,
isaac_lang/lower*.py) and the dimension it takes where that table names one.
"""
from __future__ import annotations

import re

from lark import Tree

from isaac_ir import ir
from isaac_ir import mass as M
from isaac_ir import units as U
from isaac_lang.lower_expr import Scope

from .index import TABLE_OWNERS, Definition, PropertyKey, SceneIndex, template_pattern
from .values import evaluate, format_number, format_typed, unit_of


def hover_text(index: SceneIndex, item, values: dict, scene: ir.Scene | None) -> str | None:
    """The hover of an index item (a Definition, Reference or PropertyKey), or None when there is nothing to say."""
    if isinstance(item, PropertyKey):
        return property_text(item, values, index)
    definition = index.resolve(item)
    if definition is None:
        return None
    text = _code(definition.header)
    if definition.kind == "let":
        text += "\n\n" + let_text(definition, values)
    elif definition.kind == "body":
        text += "\n\n" + body_text(definition, scene)
    elif definition.kind == "material":
        text += "\n\n" + material_text(definition, scene)
    else:
        text += f"\n\n{definition.kind} `{definition.name}`"
    if definition.span.path != index.root:
        text += f"\n\ndeclared in `{definition.span.path.name}`, line {definition.span.line}"
    return text


def let_text(definition: Definition, values: dict) -> str:
    typed = values.get(id(definition))
    if typed is None:
        typed = evaluate(definition.tree.children[1], Scope())  # a constant let inside a part or a loop has a value too
    if typed is None:
        return f"`{definition.name}`: its value depends on where it is used (a part's parameters, a loop's variable)"
    return f"`{definition.name} = {format_typed(typed)}` ({U.describe(typed.dim)})"


def body_text(definition: Definition, scene: ir.Scene | None) -> str:
    bodies = _declared(scene.bodies if scene else (), definition)
    if not bodies:
        return f"body `{definition.name}`: its shape and mass once the scene checks without errors"
    body = bodies[0]
    lines = [f"**{body.name}**: {body.motion} {_shape_text(body.shape)}"]
    lines.append(f"mass: {format_number(body.mass)} kg" if body.mass is not None else "mass: none (not dynamic)")
    if body.inertia is not None:
        moments = M.principal_moments(body.inertia)
        lines.append("inertia: principal moments (" + ", ".join(format_number(m) for m in moments) + ") kg*m2")
    if body.material:
        lines.append(f"material: {body.material}")
    if len(bodies) > 1:
        lines.append(f"(and {len(bodies) - 1} more bodies declared here: " +
                     ", ".join(b.name for b in bodies[1:4]) + (", ..." if len(bodies) > 4 else "") + ")")
    return "  \n".join(lines)


def material_text(definition: Definition, scene: ir.Scene | None) -> str:
    materials = _declared(scene.materials if scene else (), definition)
    if not materials:
        return f"material `{definition.name}`: its values once the scene checks without errors"
    material = materials[0]
    lines = [f"**{material.name}**"]
    if material.density is not None:
        lines.append(f"density: {format_number(material.density)} kg/m3")
    lines.append(f"friction: {format_number(material.friction)}, restitution: {format_number(material.restitution)}")
    if material.young is not None:
        lines.append(f"Young's modulus: {format_number(material.young)} Pa, Poisson's ratio "
                     f"{format_number(material.poisson)}")
    return "  \n".join(lines)


def property_text(key: PropertyKey, values: dict, index: SceneIndex) -> str:
    meaning = key.table.get(key.name)
    owner = TABLE_OWNERS.get(id(key.table), "this block")
    if meaning is None:
        return f"`{key.name}` is not a property of {owner}: it takes " + ", ".join(sorted(key.table))
    text = f"`{key.name}` ({owner}): {meaning}"
    dim = dimension_named(meaning)
    if dim is not None:
        text += f"  \ntakes {U.describe(dim)}, e.g. in {U.EXAMPLE_UNIT.get(dim) or unit_of(dim)}"
    written = _written_value(key, values, index)
    if written:
        text += f"  \nwritten here: {written}"
    return text


def dimension_named(meaning: str):
    """The dimension a property table's text names (`kg/m3`, `length along z`, `initial angular velocity`), or
    None when it names none (the lowering, which knows it, then says so in its diagnostic)."""
    first = re.split(r"[\s,]", meaning.strip(), maxsplit=1)[0]
    try:
        factor, dim = U.parse_unit(first)
        return dim
    except U.UnitError:
        pass
    words = sorted(((name.split(" ", 1)[1], dim) for dim, name in U.DIM_NAMES.items() if dim != U.DIMENSIONLESS),
                   key=lambda pair: -len(pair[0]))
    for words_of_dim, dim in words:
        if re.search(rf"\b{re.escape(words_of_dim)}\b", meaning):
            return dim
    return None


def _written_value(key: PropertyKey, values: dict, index: SceneIndex) -> str | None:
    """The value written after a key, evaluated with the scene's top-level `let`s (None: not a plain value)."""
    scope = Scope()
    for definition in index.definitions:
        if id(definition) in values:
            scope.values[definition.name] = values[id(definition)]
    if isinstance(key.value, Tree) and key.value.data in ("block", "range"):
        return None
    typed = evaluate(key.value, scope)
    return f"{format_typed(typed)} ({U.describe(typed.dim)})" if typed is not None else None


def _declared(declared, definition: Definition) -> list:
    """The IR items a declaration made: its name, or the names a part instance or a `{i}` loop gives it."""
    exact = [item for item in declared if item.name == definition.name]
    if exact:
        return exact
    pattern = template_pattern(definition.name)
    return [item for item in declared if pattern.fullmatch(item.name.rsplit(".", 1)[-1])]


def _shape_text(shape: ir.Shape) -> str:
    parts = [shape.type]
    if shape.radius is not None:
        parts.append(f"radius {format_number(shape.radius)} m")
    if shape.length is not None:
        parts.append(f"length {format_number(shape.length)} m")
    if shape.size is not None:
        parts.append(f"size {format_number(shape.size)} m")
    if shape.normal is not None:
        parts.append(f"normal {format_number(shape.normal)}")
    if shape.file is not None:
        parts.append(f'file "{shape.file}"')
    if shape.parts:
        parts.append(f"of {len(shape.parts)} parts")
    return ", ".join(parts)


def _code(line: str) -> str:
    return f"```isaac\n{line}\n```"
