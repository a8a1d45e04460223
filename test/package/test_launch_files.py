"""launch/cell.launch.py and rviz/cell.rviz, tested without ``launch`` (not installable here).

What can be checked: the launch file compiles; every ``Node`` of this package names an
executable of setup.py's entry points, every other package it starts is declared in
package.xml; every file it opens from the share directory is shipped (setup.py's
data_files); its arguments are documented in docs/ros.md; the RViz configuration is
YAML with fixed frame ``cake`` and shows the markers, the profile and the tool on the
topics of rheo_shaping/nodes/topics.py.
"""
from __future__ import annotations

import ast
import glob
import py_compile
import xml.etree.ElementTree as ET
from pathlib import Path

import yaml

from _support.packaging import setup_kwargs

REPO = Path(__file__).resolve().parents[2]
LAUNCH = REPO / "launch" / "cell.launch.py"
RVIZ = REPO / "rviz" / "cell.rviz"


def _tree() -> ast.Module:
    return ast.parse(LAUNCH.read_text(), str(LAUNCH))


def _kw(call: ast.Call, name: str):
    for kw in call.keywords:
        if kw.arg == name and isinstance(kw.value, ast.Constant):
            return kw.value.value
    return None


def test_launch_file_compiles(tmp_path):
    py_compile.compile(str(LAUNCH), cfile=str(tmp_path / "cell.launch.pyc"), doraise=True)


def test_launch_file_starts_only_installed_executables():
    scripts = {spec.split("=", 1)[0].strip() for spec in
               ast.literal_eval(setup_kwargs()["entry_points"])["console_scripts"]}
    setup_tree = ast.parse((REPO / "setup.py").read_text())
    scripts |= set(next(ast.literal_eval(n.value) for n in setup_tree.body   # the launchers
                        if isinstance(n, ast.Assign)
                        and getattr(n.targets[0], "id", "") == "NODES"))
    declared = {e.text.strip() for e in ET.parse(
        REPO / "package.xml").getroot().iter("exec_depend")}
    tree = _tree()
    package = next(n.value.value for n in ast.walk(tree) if isinstance(n, ast.Assign)
                   and getattr(n.targets[0], "id", "") == "PACKAGE")
    assert package == "rheo_shaping"
    nodes = [n for n in ast.walk(tree) if isinstance(n, ast.Call)
             and getattr(n.func, "id", None) == "Node"]
    started = []
    for call in nodes:
        exe, pkg = _kw(call, "executable"), _kw(call, "package")
        assert exe, ast.dump(call)
        if pkg is None or pkg == package:          # package comes from **common
            assert exe in scripts, f"{exe} is not an executable setup.py installs"
        else:
            assert pkg in declared, f"{pkg} (started by the launch file) not in package.xml"
        started.append(exe)
    assert sorted(started) == ["gap_watch", "gap_watch_managed", "lifecycle_manager", "monitor",
                               "monitor_managed", "planner", "planner_managed", "rviz2",
                               "simulator", "simulator_managed"]


def test_launch_file_opens_only_shipped_files():
    setup_src = (REPO / "setup.py").read_text()
    joins = [n for n in ast.walk(_tree()) if isinstance(n, ast.Call)
             and isinstance(n.func, ast.Attribute) and n.func.attr == "join"]
    shipped = []
    for call in joins:
        parts = [a.value for a in call.args[1:] if isinstance(a, ast.Constant)]
        if not parts:
            continue
        rel = Path(*parts)
        assert (REPO / rel).is_file(), f"the launch file opens {rel}, not in the repository"
        pattern = f"{rel.parent}/*{''.join(rel.suffixes)}"
        assert f"glob('{pattern}')" in setup_src, f"setup.py does not install {pattern}"
        assert str(REPO / rel) in glob.glob(str(REPO / pattern))
        shipped.append(str(rel))
    assert sorted(set(shipped)) == ["config/cell.yaml", "rviz/cell.rviz"]
    assert "glob('launch/*.launch.py')" in setup_src


def test_launch_arguments_are_documented():
    args = [n.args[0].value for n in ast.walk(_tree()) if isinstance(n, ast.Call)
            and getattr(n.func, "id", None) == "DeclareLaunchArgument"]
    assert sorted(args) == ["adaptive", "clock_topic", "gap_watch", "managed", "namespace",
                            "params_file", "rviz", "use_sim_time"]
    doc = (REPO / "docs" / "ros.md").read_text()
    for name in args:
        assert f"| `{name}` |" in doc, f"docs/ros.md: launch argument `{name}` not in its table"


def test_the_clock_remap_reaches_every_node_of_the_cell():
    """clock_topic:=clock moves the clock into the namespace only if the simulator's publisher
    and every time source move together: the remap is in the arguments every node of this
    package gets (``common``), and RViz's."""
    calls = [n for n in ast.walk(_tree()) if isinstance(n, ast.Call)]
    common = next(c for c in calls if getattr(c.func, "id", None) == "dict"
                  and any(k.arg == "package" for k in c.keywords))
    assert any(k.arg == "remappings" and getattr(k.value, "id", None) == "clock"
               for k in common.keywords)
    nodes = [c for c in calls if getattr(c.func, "id", None) == "Node"]
    for call in nodes:
        own = [k for k in call.keywords if k.arg == "remappings"]
        if _kw(call, "package") == "rviz2":
            assert own and getattr(own[0].value, "id", None) == "clock"
        else:
            assert not own and any(k.arg is None for k in call.keywords), ast.dump(call)


def test_rviz_config_shows_the_cell_in_frame_cake():
    from_topics = {"sheet/markers", "sheet/profile", "tool/pose"}
    cfg = yaml.safe_load(RVIZ.read_text())
    manager = cfg["Visualization Manager"]
    assert manager["Global Options"]["Fixed Frame"] == "cake"
    shown = {d["Topic"]["Value"]: d["Class"] for d in manager["Displays"] if "Topic" in d}
    assert shown["sheet/markers"] == "rviz_default_plugins/MarkerArray"
    assert shown["sheet/profile"] == "rviz_default_plugins/PoseArray"
    assert shown["tool/pose"] == "rviz_default_plugins/Pose"
    assert from_topics <= set(shown)
    topics_src = (REPO / "rheo_shaping" / "nodes" / "topics.py").read_text()
    for name in shown:
        assert f'Topic("{name}"' in topics_src, f"{name}: not a topic of nodes/topics.py"


def test_managed_launch_starts_each_managed_node_under_its_plain_name_and_the_manager():
    """``managed:=true``: simulator_managed, monitor_managed, planner_managed (and with
    ``gap_watch:=true`` gap_watch_managed) under the node names the plain ones have (the
    lifecycle manager drives ``<name>/change_state`` of its namespace), with the same
    arguments, remaps, condition and params file, and the manager beside them with those
    node_names."""
    calls = {_kw(n, "executable"): n for n in ast.walk(_tree()) if isinstance(n, ast.Call)
             and getattr(n.func, "id", None) == "Node"}
    for plain in ("simulator", "monitor", "planner", "gap_watch"):
        managed = calls[f"{plain}_managed"]
        assert _kw(managed, "name") == plain
        kwargs = {kw.arg: ast.unparse(kw.value) for kw in managed.keywords
                  if kw.arg != "executable"}
        assert kwargs == {kw.arg: ast.unparse(kw.value) for kw in calls[plain].keywords
                          if kw.arg != "executable"}, plain
    manager = calls["lifecycle_manager"]
    assert _kw(manager, "name") == "lifecycle_manager"
    # the manager's node_names: the three, and the gap watch when it is started
    args = next(kw.value for kw in manager.keywords if kw.arg == "ros_arguments")
    assert "node_names:=[" in ast.unparse(args)
    names = next(n for n in ast.walk(_tree()) if isinstance(n, ast.Assign)
                 and getattr(n.targets[0], "id", "") == "names")
    assert ast.unparse(names.value) == ("['simulator', 'monitor', 'planner'] + (['gap_watch'] "
                                        "if gap_watch else [])")
    assert [ast.unparse(kw.value) for kw in manager.keywords if kw.arg is None] == ["common"]
    from rheo_shaping.safety.lifecycle_terms import CELL_ORDER
    assert set(CELL_ORDER) == {"simulator", "monitor", "planner"}
