"""package.xml, setup.py and setup.cfg agree with what the ROS tooling expects."""
from __future__ import annotations

import ast
import configparser
import xml.etree.ElementTree as ET
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

EXEC_DEPENDS = {
    "rclpy", "std_msgs", "geometry_msgs", "trajectory_msgs", "visualization_msgs",
    "diagnostic_msgs", "rosgraph_msgs", "std_srvs",
    "python3-numpy", "python3-scipy", "python3-numba", "python3-yaml", "python3-matplotlib", "ruckig",
}
TEST_DEPENDS = {"python3-pytest"}
CONSOLE_SCRIPTS = {
    "simulator": "rheo_shaping.nodes.simulator:main",
    "planner": "rheo_shaping.nodes.planner:main",
    "monitor": "rheo_shaping.nodes.monitor:main",
    "rheo-shaping": "rheo_shaping.cli:main",
}


def _manifest() -> ET.Element:
    return ET.parse(REPO / "package.xml").getroot()


def test_package_xml_identity():
    root = _manifest()
    assert root.tag == "package" and root.get("format") == "3"
    assert root.findtext("name") == "rheo_shaping"
    assert root.findtext("version") == "0.1.0"
    assert root.findtext("license") == "Apache-2.0"
    assert (root.findtext("description") or "").strip()
    assert root.find("maintainer") is not None and root.find("maintainer").get("email")
    assert root.findtext("export/build_type") == "ament_python"


def test_package_xml_lists_every_dependency():
    root = _manifest()
    exec_deps = {e.text.strip() for e in root.iter("exec_depend")}
    exec_deps |= {e.text.strip() for e in root.iter("depend")}
    test_deps = {e.text.strip() for e in root.iter("test_depend")}
    assert EXEC_DEPENDS <= exec_deps, f"missing exec_depend: {sorted(EXEC_DEPENDS - exec_deps)}"
    assert TEST_DEPENDS <= test_deps, f"missing test_depend: {sorted(TEST_DEPENDS - test_deps)}"


def test_package_xml_version_matches_setup_py_and_package():
    import re
    setup_src = (REPO / "setup.py").read_text()
    init_src = (REPO / "rheo_shaping" / "__init__.py").read_text()
    version = _manifest().findtext("version")
    assert re.search(r"version\s*=\s*['\"]" + re.escape(version) + "['\"]", setup_src)
    assert re.search(r"__version__\s*=\s*['\"]" + re.escape(version) + "['\"]", init_src)


def _setup_kwargs() -> dict:
    tree = ast.parse((REPO / "setup.py").read_text())
    call = next(n for n in ast.walk(tree)
                if isinstance(n, ast.Call) and getattr(n.func, "id", None) == "setup")
    return {kw.arg: kw.value for kw in call.keywords}


def test_setup_py_console_scripts():
    entry_points = ast.literal_eval(_setup_kwargs()["entry_points"])
    scripts = {}
    for spec in entry_points["console_scripts"]:
        name, target = (part.strip() for part in spec.split("=", 1))
        scripts[name] = target
    assert scripts == CONSOLE_SCRIPTS


def test_setup_cfg_installs_scripts_where_ros2_run_looks():
    cfg = configparser.ConfigParser()
    cfg.read(REPO / "setup.cfg")
    assert cfg["develop"]["script_dir"] == "$base/lib/rheo_shaping"
    assert cfg["install"]["install_scripts"] == "$base/lib/rheo_shaping"


def test_ament_resource_marker_exists():
    assert (REPO / "resource" / "rheo_shaping").is_file()
