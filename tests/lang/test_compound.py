"""Compound bodies in the front end (docs/compound.md): the mass, centre and inertia of a body made of parts, and
of a mesh from its file, against closed forms; positioned errors for what cannot be a part or bounds no solid."""
from __future__ import annotations

import math

import numpy as np
import pytest

from isaac.cli import main
from isaac_ir.diagnostics import SceneError
from isaac_lang.load import load_text
from isaac_ir import mass as M

# the IR's mass properties are sums of a few products of the written numbers: exact to rounding
TIGHT = 1e-12


def body_of(text: str, name: str = "b", folder="."):
    return load_text("scene s {\n" + text + "\n}\n", "s.isaac", folder=folder).scene.body(name)


def inertia_of(body) -> np.ndarray:
    return np.asarray(body.inertia, float)


def centre_of(body) -> np.ndarray:
    """Where the centre of mass sits from the written origin (a body with no `at`): -offset."""
    return -np.asarray(body.shape.offset, float)


def close(actual, expected, scale=None):
    actual, expected = np.asarray(actual, float), np.asarray(expected, float)
    scale = np.abs(expected).max() if scale is None else scale
    np.testing.assert_allclose(actual, expected, rtol=0, atol=TIGHT * scale)


def box_moments(lo, hi) -> tuple:
    """(volume, first moments (3,), second moments S_ij = int x_i x_j dV (3,3)) of the box [lo, hi], by direct
    integration: int x^k dx over [a, b] = (b^(k+1) - a^(k+1)) / (k + 1), and the box's integrals factor."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    i0 = hi - lo
    i1 = (hi**2 - lo**2) / 2.0
    i2 = (hi**3 - lo**3) / 3.0
    volume = float(np.prod(i0))
    first = np.array([i1[k] * np.prod(np.delete(i0, k)) for k in range(3)])
    second = np.zeros((3, 3))
    for j in range(3):
        for k in range(3):
            if j == k:
                second[j, k] = i2[j] * np.prod(np.delete(i0, j))
            else:
                rest = [m for m in range(3) if m not in (j, k)][0]
                second[j, k] = i1[j] * i1[k] * i0[rest]
    return volume, first, second


def tensor_about_centre(volume, first, second, density) -> tuple:
    """(mass, centre, inertia about the centre) of a solid from its volume integrals: c = int x / V,
    S_c = S - V c c^T, I = rho (tr(S_c) E - S_c)."""
    centre = first / volume
    about = second - volume * np.outer(centre, centre)
    return density * volume, centre, density * (np.trace(about) * np.eye(3) - about)


# ---- primitives put together -------------------------------------------------------------------------------

def test_two_spheres_on_a_bar():
    r, m1, d = 0.03, 2.0, 0.25  # each ball: radius, mass, distance from the middle
    a, length, m2 = 0.005, 0.44, 0.3  # the bar, a cylinder along x
    body = body_of(f"""
  body b compound {{
    part left sphere {{ radius {r} m  mass {m1} kg  at (-{d}, 0, 0) m }}
    part right sphere {{ radius {r} m  mass {m1} kg  at ({d}, 0, 0) m }}
    part bar cylinder {{ radius {a} m  length {length} m  mass {m2} kg  orient (0, 90, 0) }}
  }}""")
    assert body.mass == pytest.approx(2 * m1 + m2, rel=TIGHT)
    close(centre_of(body), (0, 0, 0), scale=d)
    # about the bar's axis: two balls 2/5 m r^2 and the cylinder's m a^2 / 2;
    # across: each ball 2/5 m r^2 + m d^2 (parallel axes), the cylinder m (3 a^2 + L^2) / 12
    along = 2 * 0.4 * m1 * r**2 + 0.5 * m2 * a**2
    across = 2 * (0.4 * m1 * r**2 + m1 * d**2) + m2 * (3 * a**2 + length**2) / 12
    close(inertia_of(body), np.diag([along, across, across]))


def test_a_box_of_two_half_boxes_is_the_whole_box():
    whole = body_of("body b box { size (20, 10, 6) cm  density 2700 kg/m3 }")
    halves = body_of("""
  body b compound {
    density 2700 kg/m3
    part west box { size (10, 10, 6) cm  at (-5, 0, 0) cm }
    part east box { size (10, 10, 6) cm  at (5, 0, 0) cm }
  }""")
    assert halves.mass == pytest.approx(whole.mass, rel=TIGHT)
    close(centre_of(halves), (0, 0, 0), scale=0.1)
    close(inertia_of(halves), inertia_of(whole))


def test_an_L_of_two_boxes_has_products_of_inertia():
    """The L [0,2]x[0,2] less [1,2]x[1,2] (cm), 1 cm thick, written as two boxes; its closed form is integrated
    the other way round, the big square minus the missing corner, so the parallel axis theorem is not used."""
    rho = 1000.0
    body = body_of(f"""
  body b compound {{
    density {rho} kg/m3
    part foot box {{ size (2, 1, 1) cm  at (1, 0.5, 0.5) cm }}
    part leg box {{ size (1, 1, 1) cm  at (0.5, 1.5, 0.5) cm }}
  }}""")
    V1, f1, S1 = box_moments((0, 0, 0), (0.02, 0.02, 0.01))
    V2, f2, S2 = box_moments((0.01, 0.01, 0), (0.02, 0.02, 0.01))
    mass, centre, inertia = tensor_about_centre(V1 - V2, f1 - f2, S1 - S2, rho)
    assert body.mass == pytest.approx(mass, rel=TIGHT)
    close(centre_of(body), centre, scale=0.02)
    close(inertia_of(body), inertia)
    # the product I_xy = -rho int (x - cx)(y - cy) dV is not zero (the L is not symmetric about x or y)
    assert inertia[0, 1] > 0.05 * inertia[0, 0]
    assert body.inertia[0][1] == pytest.approx(inertia[0, 1], rel=1e-10)


def test_a_rotated_part_turns_its_inertia():
    """A box part turned 30 deg about z: I = R diag(Ia, Ib, Ic) R^T, so I_xx = c^2 Ia + s^2 Ib,
    I_yy = s^2 Ia + c^2 Ib, I_xy = c s (Ia - Ib)."""
    m, (a, b, c) = 3.0, (0.4, 0.1, 0.05)
    body = body_of(f"""
  body b compound {{
    part slab box {{ size ({a}, {b}, {c}) m  mass {m} kg  orient (0, 0, 30) }}
  }}""")
    Ia, Ib, Ic = m * (b * b + c * c) / 12, m * (a * a + c * c) / 12, m * (a * a + b * b) / 12
    co, si = math.cos(math.radians(30)), math.sin(math.radians(30))
    expected = np.array([[co * co * Ia + si * si * Ib, co * si * (Ia - Ib), 0],
                         [co * si * (Ia - Ib), si * si * Ia + co * co * Ib, 0],
                         [0, 0, Ic]])
    close(inertia_of(body), expected)


def test_a_part_turned_about_a_skew_axis_keeps_its_principal_moments():
    m, (a, b, c) = 1.5, (0.3, 0.2, 0.1)
    body = body_of(f"""
  body b compound {{
    part slab box {{ size ({a}, {b}, {c}) m  mass {m} kg  orient (20, 35, -50)  at (0.1, 0.2, 0.3) m }}
  }}""")
    moments = sorted([m * (b * b + c * c) / 12, m * (a * a + c * c) / 12, m * (a * a + b * b) / 12])
    close(np.linalg.eigvalsh(inertia_of(body)), moments, scale=moments[-1])
    close(centre_of(body), (0.1, 0.2, 0.3), scale=0.3)


def test_the_body_mass_is_shared_by_volume_and_a_part_mass_wins():
    body = body_of("""
  body b compound {
    mass 10 kg
    part big box { size (2, 1, 1) m }
    part small box { size (1, 1, 1) m  at (3, 0, 0) m }
    part tag sphere { radius 1 cm  mass 1 kg  at (-2, 0, 0) m }
  }""")
    masses = {p.name: p.mass for p in body.shape.parts}
    # what the tag's own kilogram leaves, 9 kg, shared 2 : 1 by volume
    assert masses == pytest.approx({"big": 6.0, "small": 3.0, "tag": 1.0}, rel=TIGHT)
    assert body.mass == pytest.approx(10.0, rel=TIGHT)
    close(centre_of(body), ((0 * 6 + 3 * 3 - 2 * 1) / 10, 0, 0), scale=3)


def test_each_part_takes_its_own_materials_density():
    body = body_of("""
  material steel { density 7850 kg/m3 }
  material oak { density 700 kg/m3 }
  body b compound {
    material oak
    part handle box { size (2, 20, 2) cm }
    part head cylinder { radius 2 cm  length 8 cm  at (0, 12, 0) cm  orient (0, 90, 0)  material steel }
  }""")
    handle, head = body.shape.parts
    assert (handle.material, head.material) == ("oak", "steel")
    assert handle.mass == pytest.approx(700 * 0.02 * 0.2 * 0.02, rel=TIGHT)
    assert head.mass == pytest.approx(7850 * math.pi * 0.02**2 * 0.08, rel=TIGHT)
    close(centre_of(body), (0, 0.12 * head.mass / (handle.mass + head.mass), 0), scale=0.12)


def test_at_places_the_written_origin_and_orient_turns_it():
    """The body's `at` is where its written origin goes, so its centre of mass is at + R(orient) c."""
    text = """
  body b compound {{
    {pose}
    part ball sphere {{ radius 1 cm  mass 1 kg  at (0.3, 0, 0) m }}
    part core sphere {{ radius 1 cm  mass 2 kg }}
  }}
  body floor plane {{ }}
  constraint pin nail(b @ (0, 0, 0), (1, 2, 3) m)"""
    body = body_of(text.format(pose="at (1, 2, 3) m  orient (0, 0, 90)"))
    centre = np.array([0.1, 0.0, 0.0])  # (0.3 * 1 + 0 * 2) / 3 in the written frame
    turned = np.array([0.0, 0.1, 0.0])  # turned 90 deg about z
    close(body.position.value, np.array([1, 2, 3]) + turned, scale=3)
    close(centre_of(body), centre, scale=0.3)
    scene = load_text("scene s {\n" + text.format(pose="at (1, 2, 3) m  orient (0, 0, 90)") + "\n}\n",
                      "s.isaac").scene
    # the nailed point `b @ (0, 0, 0)` is the written origin: -c from the centre of mass, in body axes
    params = dict(scene.constraints[0].terms[0].params)
    close(params["point"], -centre, scale=0.3)


def test_inertia_on_the_body_overrides_the_parts():
    body = body_of("""
  body b compound {
    inertia (1, 2, 3) kg*m2
    part one sphere { radius 1 cm  mass 1 kg }
  }""")
    assert body.inertia == ((1.0, 0.0, 0.0), (0.0, 2.0, 0.0), (0.0, 0.0, 3.0))


# ---- meshes: volume integrals ------------------------------------------------------------------------------

def write_obj(path, vertices, faces) -> str:
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in vertices]
    lines += ["f " + " ".join(str(i + 1) for i in face) for face in faces]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path.name


CUBE_VERTICES = [(x, y, z) for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)]
# outward, counter-clockwise seen from outside (vertex k = 4x + 2y + z)
CUBE_FACES = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6),
              (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
TETRA_VERTICES = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
TETRA_FACES = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


def test_a_unit_cube_mesh_has_the_cubes_inertia(tmp_path):
    name = write_obj(tmp_path / "cube.obj", CUBE_VERTICES, CUBE_FACES)
    body = body_of(f'body b mesh {{ file "{name}"  density 1000 kg/m3  at (2, 0, 0) m }}', folder=tmp_path)
    # m = rho V = 1000 kg; I = m (1 + 1) / 12 about each axis; the centre is the cube's middle
    assert body.mass == pytest.approx(1000.0, rel=TIGHT)
    close(inertia_of(body), np.eye(3) * 1000.0 / 6.0)
    close(centre_of(body), (0.5, 0.5, 0.5), scale=1)
    close(body.position.value, (2.5, 0.5, 0.5), scale=2)  # `at` places the file's origin


def test_a_tetrahedron_mesh_against_its_dirichlet_integrals(tmp_path):
    """The corner tetrahedron: int x^a y^b z^c dV = a! b! c! / (a + b + c + 3)!, so V = 1/6, int x = 1/24,
    int x^2 = 1/60, int x y = 1/120: about the centroid (1/4, 1/4, 1/4), S_xx = 1/60 - V/16 = 1/160 and
    S_xy = 1/120 - V/16 = -1/480, hence I_xx = 2/160 rho and I_xy = 1/480 rho."""
    name = write_obj(tmp_path / "tetra.obj", TETRA_VERTICES, TETRA_FACES)
    body = body_of(f'body b mesh {{ file "{name}"  mass 6 kg }}', folder=tmp_path)
    rho = 6.0 / (1.0 / 6.0)
    expected = rho * np.array([[1 / 80, 1 / 480, 1 / 480], [1 / 480, 1 / 80, 1 / 480], [1 / 480, 1 / 480, 1 / 80]])
    close(inertia_of(body), expected)
    close(centre_of(body), (0.25, 0.25, 0.25), scale=1)


def icosahedron(edge: float) -> tuple:
    """The regular icosahedron's 12 vertices (0, +-1, +-phi) cyclically, scaled to the edge, and its 20 faces
    (the triples of mutually adjacent vertices), wound outward."""
    phi = (1 + math.sqrt(5)) / 2
    base = [(0, s, t * phi) for s in (-1, 1) for t in (-1, 1)]
    vertices = np.array([v[k:] + v[:k] for k in range(3) for v in base], float) * (edge / 2)
    faces = []
    near = [set(np.nonzero(np.isclose(np.linalg.norm(vertices - v, axis=1), edge))[0]) for v in vertices]
    for i in range(12):
        for j in near[i]:
            for k in near[i] & near[j]:
                if i < j < k:
                    a, b, c = vertices[i], vertices[j], vertices[k]
                    outward = np.dot(np.cross(b - a, c - a), a + b + c) > 0
                    faces.append((i, j, k) if outward else (i, k, j))
    assert len(faces) == 20
    return vertices, faces


def test_an_icosahedron_mesh_against_its_closed_form(tmp_path):
    """A solid regular icosahedron of edge a: I = m a^2 phi^2 / 10 about every axis through its centre."""
    edge, m = 0.07, 2.0
    vertices, faces = icosahedron(edge)
    name = write_obj(tmp_path / "ico.obj", vertices + (0.1, -0.2, 0.3), faces)
    body = body_of(f'body b mesh {{ file "{name}"  mass {m} kg }}', folder=tmp_path)
    phi = (1 + math.sqrt(5)) / 2
    close(inertia_of(body), np.eye(3) * m * edge**2 * phi**2 / 10)
    close(centre_of(body), (0.1, -0.2, 0.3), scale=0.3)
    # and its volume, 5 (3 + sqrt 5) a^3 / 12
    volume, _, _ = M.mesh_integrals(vertices, faces)
    assert volume == pytest.approx(5 * (3 + math.sqrt(5)) * edge**3 / 12, rel=TIGHT)


def test_the_shipped_icosahedron_asset_has_its_closed_form():
    """scenes/assets/icosahedron.obj: circumradius 0.05 m written to 10 digits, so the closed form holds to ~1e-9."""
    from pathlib import Path

    assets = Path(__file__).resolve().parents[2] / "scenes"
    body = body_of('body b mesh { file "assets/icosahedron.obj"  mass 1 kg }', folder=assets)
    phi = (1 + math.sqrt(5)) / 2
    edge = 2 * 0.05 / math.sqrt(phi * math.sqrt(5))  # circumradius = a sqrt(phi sqrt 5) / 2
    np.testing.assert_allclose(inertia_of(body), np.eye(3) * edge**2 * phi**2 / 10, rtol=0,
                               atol=1e-8 * edge**2)


def test_a_clockwise_mesh_is_the_same_solid(tmp_path):
    name = write_obj(tmp_path / "cw.obj", CUBE_VERTICES, [f[::-1] for f in CUBE_FACES])
    body = body_of(f'body b mesh {{ file "{name}"  mass 6 kg }}', folder=tmp_path)
    close(inertia_of(body), np.eye(3))


def test_a_mesh_part_in_a_compound(tmp_path):
    """A unit-cube mesh part and a box part of the same size beside it: the whole is a 2 x 1 x 1 box."""
    name = write_obj(tmp_path / "cube.obj", CUBE_VERTICES, CUBE_FACES)
    body = body_of(f"""
  body b compound {{
    density 500 kg/m3
    part mesh_half mesh {{ file "{name}" }}
    part box_half box {{ size (1, 1, 1) m  at (1.5, 0.5, 0.5) m }}
  }}""", folder=tmp_path)
    whole = body_of("body b box { size (2, 1, 1) m  density 500 kg/m3 }")
    assert body.mass == pytest.approx(whole.mass, rel=TIGHT)
    close(inertia_of(body), inertia_of(whole))
    close(centre_of(body), (1, 0.5, 0.5), scale=1)


def test_mass_and_inertia_given_keep_the_files_origin_as_the_centre(tmp_path):
    name = write_obj(tmp_path / "cube.obj", CUBE_VERTICES, CUBE_FACES)
    body = body_of(f'body b mesh {{ file "{name}"  mass 1 kg  inertia (1, 2, 3) kg*m2 }}', folder=tmp_path)
    assert body.inertia == ((1.0, 0.0, 0.0), (0.0, 2.0, 0.0), (0.0, 0.0, 3.0))
    assert body.shape.offset == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("damage,message", [
    (lambda f: f[:-1], "bounds no solid: the mesh is not closed"),
    (lambda f: f[:3] + [f[3][::-1]] + f[4:], "bounds no solid: an edge is used twice in the same direction"),
])
def test_a_mesh_that_bounds_no_solid_is_a_positioned_error(tmp_path, capsys, damage, message):
    name = write_obj(tmp_path / "bad.obj", CUBE_VERTICES, damage(list(CUBE_FACES)))
    assert_mesh_error(tmp_path, capsys, name, message)


def test_a_flat_mesh_is_a_positioned_error(tmp_path, capsys):
    flat = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (1.0, 1.0, 0.0)]
    name = write_obj(tmp_path / "flat.obj", flat, TETRA_FACES)
    # (the check of the files a scene names may see that it is flat before its mass is integrated)
    assert_mesh_error(tmp_path, capsys, name, "flat", "encloses no volume")
    with pytest.raises(M.MeshMassError, match="encloses no volume"):
        M.mesh_integrals(np.array(flat), np.array(TETRA_FACES))


def assert_mesh_error(folder, capsys, name, *messages):
    """`isaac check` of a body of this mesh: exit 2, the error at the `file` value with a caret, one of the
    messages, no traceback."""
    scene = folder / "s.isaac"
    scene.write_text(f'scene s {{\n  body b mesh {{ file "{name}"  density 1000 kg/m3 }}\n}}\n', encoding="utf-8")
    code = main(["check", str(scene)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    assert f"{scene}:2:22: error: " in err and any(m in err for m in messages), err
    assert "^" in err


# ---- what is not a part ------------------------------------------------------------------------------------

@pytest.mark.parametrize("part,line,col,message", [
    ("part p plane { }", 3, 12, "a plane cannot be a part"),
    ("part p compound { }", 3, 12, "a part is one shape, not a compound"),
    ("part p box { }", 3, 10, "a box needs `size`"),
    ("part p cylinder { radius 1 cm }", 3, 10, "a cylinder needs `length`"),
    ("part p sphere { radius 1 cm  mas 1 kg }", 3, 34, "mas"),
    ("part p dynamic sphere { radius 1 cm }", 3, 12, "moves with its body"),
    ("part p spher { radius 1 cm }", 3, 12, "`spher` is not a shape a part can have"),
])
def test_what_cannot_be_a_part_is_a_positioned_error(part, line, col, message):
    text = "scene s {\n  body b compound {\n    " + part + "\n    part q sphere { radius 1 cm  mass 1 kg }\n  }\n}\n"
    with pytest.raises(SceneError) as raised:
        load_text(text, "s.isaac")
    found = [d for d in raised.value.diagnostics if message in d.message]
    assert found, [d.message for d in raised.value.diagnostics]
    assert (found[0].pos.line, found[0].pos.col) == (line, col)


def test_an_unknown_part_property_suggests_the_right_one():
    text = "scene s {\n  body b compound {\n    part p sphere { radius 1 cm  denisty 1000 kg/m3 }\n  }\n}\n"
    with pytest.raises(SceneError) as raised:
        load_text(text, "s.isaac")
    diagnostic = raised.value.diagnostics[0]
    assert "denisty" in diagnostic.message and "density" in (diagnostic.hint or "") + diagnostic.message
    assert (diagnostic.pos.line, diagnostic.pos.col) == (3, 34)


@pytest.mark.parametrize("text,message", [
    ("body b compound { mass 1 kg }", "a compound body is made of parts"),
    ("body b sphere { radius 1 cm  mass 1 kg  part p sphere { radius 1 cm } }", "a body made of parts is a compound"),
    ("body b compound { radius 1 cm  part p sphere { radius 1 cm  mass 1 kg } }", "`radius` belongs in a part"),
    ("body b compound { part p sphere { radius 1 cm } }", "part `p` of body `b` has no mass"),
    ("body b compound { part p sphere { radius 1 cm  mass 1 kg }  part p box { size (1, 1, 1) cm  mass 1 kg } }",
     "part `p` is declared twice"),
    ("body b compound { mass 1 kg  part p sphere { radius 1 cm  mass 2 kg } }", "add up to 2 kg"),
])
def test_a_compound_body_that_is_not_well_made_is_a_positioned_error(text, message):
    with pytest.raises(SceneError) as raised:
        load_text("scene s {\n  " + text + "\n}\n", "s.isaac")
    found = [d for d in raised.value.diagnostics if message in d.message]
    assert found, [d.message for d in raised.value.diagnostics]
    assert found[0].pos is not None and found[0].pos.line == 2


def test_a_loop_of_parts():
    """Twelve teeth around a wheel, by a loop: the centre stays on the axis and I_xx = I_yy (a symmetric ring)."""
    body = body_of("""
  body b compound {
    density 1000 kg/m3
    part hub cylinder { radius 3 cm  length 1 cm }
    for k in 0 .. 12 {
      let a = k * 30 deg
      part tooth_{k} box { size (1, 1, 1) cm  at (4 * cos(a), 4 * sin(a), 0) cm  orient (0, 0, k * 30) }
    }
  }""")
    assert [p.name for p in body.shape.parts][:3] == ["hub", "tooth_0", "tooth_1"]
    assert len(body.shape.parts) == 13
    inertia = inertia_of(body)
    close(centre_of(body), (0, 0, 0), scale=0.04)
    assert inertia[0, 0] == pytest.approx(inertia[1, 1], rel=1e-12)
    tooth = 1000 * 1e-6
    hub = 1000 * math.pi * 0.03**2 * 0.01
    # about z: the hub m r^2 / 2, each tooth its own m (a^2 + a^2) / 12 plus m d^2
    close(inertia[2, 2], 0.5 * hub * 0.03**2 + 12 * (tooth * 2e-4 / 12 + tooth * 0.04**2))


def test_a_bad_part_on_the_command_line_is_a_caret_and_a_hint(tmp_path, capsys):
    scene = tmp_path / "s.isaac"
    scene.write_text("scene s {\n  body b compound {\n    part p box { sise (1, 1, 1) cm  mass 1 kg }\n  }\n}\n",
                     encoding="utf-8")
    code = main(["check", str(scene)])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert f"{scene}:3:18: error: " in err and "sise" in err
    assert "size" in err.split("error:", 1)[1] and "^" in err
