"""The pytest plugin: `pytest` in a user's project collects every scene that has goldens and checks it."""
from __future__ import annotations

from isaac.golden import check_scene

pytest_plugins = ["pytester"]

SCENE = """scene drop {
  time 0 s .. 0.5 s
  frames 20 Hz
  body ball sphere { radius 5 cm  mass 1 kg  at (0, 1, 0) }
}
"""


def test_the_plugin_is_registered_in_this_session(pytestconfig):
    assert pytestconfig.pluginmanager.has_plugin("isaac")


def test_a_project_with_goldens_is_checked_by_pytest_alone(pytester):
    scenes = pytester.mkdir("scenes")
    scene = scenes / "drop.isaac"
    scene.write_text(SCENE, encoding="utf-8")
    (scenes / "no_golden.isaac").write_text(SCENE, encoding="utf-8")  # no goldens: not collected
    assert check_scene(scene, update=True).status == "written"
    result = pytester.runpytest_subprocess("-q")
    result.assert_outcomes(passed=1)
    scene.write_text(SCENE.replace("mass 1 kg", "mass 2 kg").replace("(0, 1, 0)", "(0, 2, 0)"), encoding="utf-8")
    result = pytester.runpytest_subprocess("-q")
    result.assert_outcomes(failed=1)
    text = result.stdout.str()
    assert "golden mismatch" in text and "bodies[ball].mass: 2.0, the golden has 1.0" in text
    assert "position of `ball`: off by up to" in text and "Traceback" not in text


def test_update_from_pytest_and_a_broken_scene(pytester):
    scene = pytester.path / "drop.isaac"
    scene.write_text(SCENE, encoding="utf-8")
    check_scene(scene, update=True)
    scene.write_text(SCENE.replace("0.5 s", "0.4 s"), encoding="utf-8")
    pytester.runpytest_subprocess("-q", "--isaac-update").assert_outcomes(passed=1)
    pytester.runpytest_subprocess("-q").assert_outcomes(passed=1)
    scene.write_text(SCENE.replace("radius 5 cm", "radius 5"), encoding="utf-8")
    result = pytester.runpytest_subprocess("-q")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*drop.isaac:4:29: error: `radius` needs a unit*"])
    pytester.runpytest_subprocess("-q", "-p", "no:isaac").assert_outcomes()
