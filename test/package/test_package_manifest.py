"""package.xml, setup.py and setup.cfg agree with what the ROS tooling expects."""
from __future__ import annotations

import ast
import configparser
import xml.etree.ElementTree as ET
from pathlib import Path

from _support.packaging import setup_kwargs

REPO = Path(__file__).resolve().parents[2]

#: The rosdep key of every third-party module the package may import. Each key resolves
#: on Jazzy: ROS packages of jazzy/distribution.yaml, system/pip keys of
#: rosdep/python.yaml (ros/rosdistro, 2026-08).
MODULE_KEYS = {
    "rclpy": "rclpy", "rcl_interfaces": "rcl_interfaces",
    "builtin_interfaces": "builtin_interfaces", "std_msgs": "std_msgs",
    "geometry_msgs": "geometry_msgs", "trajectory_msgs": "trajectory_msgs",
    "visualization_msgs": "visualization_msgs", "diagnostic_msgs": "diagnostic_msgs",
    "rosgraph_msgs": "rosgraph_msgs", "std_srvs": "std_srvs", "lifecycle_msgs": "lifecycle_msgs",
    "tf2_msgs": "tf2_msgs",
    "launch": "launch", "launch_ros": "launch_ros", "ament_index_python": "ament_index_python",
    "numpy": "python3-numpy", "scipy": "python3-scipy", "yaml": "python3-yaml",
    "matplotlib": "python3-matplotlib", "tqdm": "python3-tqdm", "numba": "python3-numba",
    "rosbags": "python3-rosbags-pip",
}
#: Modules no rosdep key provides, with the documented command that does.
PIP_ONLY = {"ruckig": "pip install ruckig",
            # optional: only `--executor dask://HOST:PORT` imports it (docs/scale-out.md)
            "distributed": "pip install 'dask[distributed]'"}
#: Keys of rosdistro that the manifest may use (the ones above, and rviz2 for the
#: RViz configuration): a misspelt key would make `rosdep install` fail.
#: The tests' own third-party modules (imported, or run as ``python -m``) and their keys
#: (rosdep/python.yaml): pytest, the property tests' hypothesis, and the lint and type
#: tests' flake8 (test/package/test_lint.py) and mypy (test/_support/typecheck.py).
TEST_MODULE_KEYS = {"pytest": "python3-pytest", "hypothesis": "python3-hypothesis",
                    "flake8": "python3-flake8", "mypy": "python3-mypy"}
TEST_DEPENDS = set(TEST_MODULE_KEYS.values())
JAZZY_KEYS = set(MODULE_KEYS.values()) | {"rviz2"} | TEST_DEPENDS
EXEC_DEPENDS = set(MODULE_KEYS.values()) | {"rviz2"}
#: Modules some tests use that no rosdep key provides: colcon (test_colcon_layout.py skips
#: without it) and mcap's readers (test_record_independent_reader.py; PyPI only, from
#: requirements-ros.txt).
TEST_WITHOUT_KEY = {"colcon_core", "mcap", "mcap_ros2"}
#: Domains that can never be a maintainer's address (RFC 2606, RFC 6761).
RESERVED_DOMAINS = (".invalid", ".example", ".test", ".localhost", "example.com", "example.net",
                    "example.org")
#: The product's command and the validation's (rheo_shaping_validation, beside the product).
CONSOLE_SCRIPTS = {"rheo-shaping": "rheo_shaping.cli:main",
                   "rheo-shaping-validation": "rheo_shaping_validation.cli:main"}
#: The nodes' executables: setup.py's LAUNCHER (``scripts``), not console_scripts wrappers.
NODES = ("simulator", "planner", "monitor", "simulator_managed", "planner_managed",
         "monitor_managed", "gap_watch_managed", "lifecycle_manager", "gap_watch")


def _manifest() -> ET.Element:
    return ET.parse(REPO / "package.xml").getroot()


def test_package_xml_identity():
    root = _manifest()
    assert root.tag == "package" and root.get("format") == "3"
    assert root.findtext("name") == "rheo_shaping"
    assert root.findtext("version") == "0.1.0"
    assert root.findtext("license") == "Apache-2.0"
    assert (root.findtext("description") or "").strip()
    maintainer = root.find("maintainer")
    assert maintainer is not None
    assert (maintainer.text, maintainer.get("email")) == ("rheo_shaping maintainers",
                                                          "maintainers@rheo-shaping.org")
    assert root.findtext("export/build_type") == "ament_python"


def test_package_xml_lists_every_dependency():
    root = _manifest()
    exec_deps = {e.text.strip() for e in root.iter("exec_depend")}
    exec_deps |= {e.text.strip() for e in root.iter("depend")}
    test_deps = {e.text.strip() for e in root.iter("test_depend")}
    assert EXEC_DEPENDS <= exec_deps, f"missing exec_depend: {sorted(EXEC_DEPENDS - exec_deps)}"
    assert TEST_DEPENDS <= test_deps, f"missing test_depend: {sorted(TEST_DEPENDS - test_deps)}"


def test_maintainer_address_is_one_a_release_accepts():
    """bloom refuses a placeholder: an address on a reserved domain is not one."""
    import re
    for maintainer in _manifest().iter("maintainer"):
        email = maintainer.get("email") or ""
        assert re.fullmatch(r"[\w.+-]+@[\w-]+(\.[\w-]+)+", email), email
        assert not email.lower().endswith(RESERVED_DOMAINS), f"{email}: a reserved domain"


def test_every_module_the_tests_use_is_a_test_dependency():
    """colcon test needs them: each third-party module the tests import, or run with
    ``python -m``, is a runtime dependency or has its <test_depend>."""
    import re
    import sys
    declared = {e.text.strip() for e in _manifest().iter("test_depend")}
    used: set[str] = set()
    for path in (REPO / "test").rglob("*.py"):
        text = path.read_text()
        used |= set(re.findall(r'sys\.executable, "-m", "(\w+)"', text))
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.Import):
                used |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                used.add(node.module.split(".")[0])
    third_party = {m for m in used if m not in sys.stdlib_module_names
                   and m not in ("rheo_shaping", "rheo_shaping_validation", "_support")
                   and m not in MODULE_KEYS
                   and m not in PIP_ONLY}
    assert {"pytest", "hypothesis", "flake8", "mypy"} <= third_party, "the scan works"
    for module in sorted(third_party - TEST_WITHOUT_KEY):
        assert module in TEST_MODULE_KEYS, f"the tests use {module}: add its rosdep key"
        assert TEST_MODULE_KEYS[module] in declared, \
            f"package.xml: <test_depend>{TEST_MODULE_KEYS[module]}</test_depend> missing"


def test_package_xml_declares_each_dependency_once():
    """A key declared twice (under any of the depend tags) is a copy that can drift."""
    root = _manifest()
    tags = ("depend", "build_depend", "build_export_depend", "exec_depend", "test_depend",
            "doc_depend", "buildtool_depend")
    seen: dict[str, list[str]] = {}
    for tag in tags:
        for e in root.iter(tag):
            seen.setdefault(e.text.strip(), []).append(tag)
    twice = {key: where for key, where in seen.items() if len(where) > 1}
    assert not twice, f"package.xml declares these keys more than once: {twice}"


def test_license_file_is_the_license_package_xml_and_setup_py_name():
    """LICENSE holds the full Apache-2.0 text; package.xml, setup.py's license and its
    classifier all say Apache-2.0."""
    text = (REPO / "LICENSE").read_text()
    assert "Apache License" in text and "Version 2.0, January 2004" in text
    assert "TERMS AND CONDITIONS FOR USE, REPRODUCTION, AND DISTRIBUTION" in text
    assert "END OF TERMS AND CONDITIONS" in text and len(text) > 10000, "the full text"
    assert _manifest().findtext("license") == "Apache-2.0"
    kwargs = setup_kwargs()
    assert ast.literal_eval(kwargs["license"]) == "Apache-2.0"
    classifiers = ast.literal_eval(kwargs["classifiers"])
    licenses = [c for c in classifiers if c.startswith("License ::")]
    assert licenses == ["License :: OSI Approved :: Apache Software License"]


def _third_party_imports() -> dict[str, set[str]]:
    """Top-level modules imported anywhere in rheo_shaping/, rheo_shaping_validation/ (setup.py
    installs both) and launch/ -> files."""
    import sys
    found: dict[str, set[str]] = {}
    files = [*(REPO / "rheo_shaping").rglob("*.py"),
             *(REPO / "rheo_shaping_validation").rglob("*.py"), *(REPO / "launch").glob("*.py")]
    for path in files:
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            for name in names:
                top = name.split(".")[0]
                if top not in sys.stdlib_module_names and top not in ("rheo_shaping",
                                                                      "rheo_shaping_validation"):
                    found.setdefault(top, set()).add(str(path.relative_to(REPO)))
    return found


def test_every_third_party_import_is_declared_with_a_jazzy_key():
    root = _manifest()
    declared = {e.text.strip() for tag in ("exec_depend", "depend") for e in root.iter(tag)}
    imports = _third_party_imports()
    assert {"rclpy", "numpy", "rosbags", "tqdm", "ruckig"} <= set(imports), "the scan works"
    for module, files in sorted(imports.items()):
        if module in PIP_ONLY:
            continue
        assert module in MODULE_KEYS, (f"{module} (imported by {sorted(files)}) has no rosdep "
                                       f"key: add it to MODULE_KEYS and package.xml")
        assert MODULE_KEYS[module] in declared, \
            f"package.xml: <exec_depend>{MODULE_KEYS[module]}</exec_depend> missing for {module}"
    assert declared <= JAZZY_KEYS, f"keys not known on Jazzy: {sorted(declared - JAZZY_KEYS)}"


def test_pip_only_modules_are_documented():
    readme = (REPO / "README.md").read_text()
    manifest = (REPO / "package.xml").read_text()
    for module, command in PIP_ONLY.items():
        assert command in readme, f"README.md must tell users to `{command}`"
        assert command in manifest


def test_package_xml_version_matches_setup_py_and_package():
    import re
    setup_src = (REPO / "setup.py").read_text()
    init_src = (REPO / "rheo_shaping" / "__init__.py").read_text()
    version = _manifest().findtext("version")
    assert re.search(r"version\s*=\s*['\"]" + re.escape(version) + "['\"]", setup_src)
    assert re.search(r"__version__\s*=\s*['\"]" + re.escape(version) + "['\"]", init_src)


def test_setup_py_console_scripts():
    entry_points = ast.literal_eval(setup_kwargs()["entry_points"])
    scripts = {}
    for spec in entry_points["console_scripts"]:
        name, target = (part.strip() for part in spec.split("=", 1))
        scripts[name] = target
    assert scripts == CONSOLE_SCRIPTS


QUOTES = "'''"


def test_each_node_executable_is_the_launcher_shell_and_python_at_once():
    """setup.py installs its LAUNCHER per node (``scripts``): a shell script that starts Python
    on itself with SIGINT and SIGTERM blocked, and a Python script that runs the node
    (docs/safety.md; test/nodes/test_early_signals.py runs the installed ones)."""
    tree = ast.parse((REPO / "setup.py").read_text())
    consts = {t.id: n.value for n in tree.body if isinstance(n, ast.Assign)
              for t in n.targets if isinstance(t, ast.Name)}
    assert ast.literal_eval(consts["NODES"]) == NODES
    kwargs = setup_kwargs()
    assert ast.unparse(kwargs["scripts"]) == "[os.path.join('launchers', node) for node in NODES]"
    assert ast.unparse(kwargs["cmdclass"]) == \
        "{'build_scripts': BuildLaunchers, 'develop': DevelopLaunchers}"
    template = ast.literal_eval(consts["LAUNCHER"])
    for node in NODES:
        text = template.replace("@NODE@", node).replace("@PYTHON@", "/usr/bin/python3")
        text = text.replace("@BLOCK@", "env --block-signal=INT --block-signal=TERM ")
        assert text.startswith("#!/bin/sh\n")
        assert 'exec env --block-signal=INT --block-signal=TERM "$py" "$0" "$@"' in text
        # no child of the shell before the exec: dash clears its signal mask on each wait
        shell = text.split(QUOTES)[1]
        assert shell.count("env ") == 1 and "if " not in shell
        assert f"from rheo_shaping.nodes.entry import {node}\n" in text
        # the node only as the main script: a spawned worker imports it as __mp_main__
        assert "if __name__ == '__main__':" in text and f"sys.exit({node}())" in text
        compile(text, node, "exec")


def test_setup_cfg_installs_scripts_where_ros2_run_looks():
    cfg = configparser.ConfigParser()
    cfg.read(REPO / "setup.cfg")
    assert cfg["develop"]["script_dir"] == "$base/lib/rheo_shaping"
    assert cfg["install"]["install_scripts"] == "$base/lib/rheo_shaping"


def test_ament_resource_marker_exists():
    assert (REPO / "resource" / "rheo_shaping").is_file()


def test_the_vendored_tf2_msgs_is_licensed_and_hidden_from_colcon():
    """vendor/tf2_msgs (dev.py builds it into .venv, where no wheel has tf2_msgs) carries
    its BSD license and a COLCON_IGNORE: a workspace uses the system's tf2_msgs."""
    vendor = REPO / "vendor" / "tf2_msgs"
    assert (vendor / "COLCON_IGNORE").is_file()
    assert "BSD 3-Clause License" in (vendor / "LICENSE").read_text()
    assert ET.parse(vendor / "package.xml").getroot().findtext("name") == "tf2_msgs"
    assert (vendor / "msg" / "TFMessage.msg").read_text().split() == \
        ["geometry_msgs/TransformStamped[]", "transforms"]
