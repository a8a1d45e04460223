"""The package's layering: the core imports no ROS, the subpackages form no cycle.

Read from the source (ast), so it runs in either virtualenv and sees imports inside
functions too.  docs/architecture.md draws the same graph.
"""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

PKG = Path(__file__).resolve().parents[2] / "rheo_shaping"
#: The validation package beside it: the worlds, the benchmark, the campaigns.
VALIDATION = PKG.parent / "rheo_shaping_validation"

#: Top-level module names that are ROS: rclpy, its launch tools and message packages.
ROS_ROOTS = {"rclpy", "rosidl_runtime_py", "launch", "launch_ros", "ament_index_python",
             "rosbag2_py", "std_msgs", "std_srvs", "geometry_msgs", "sensor_msgs",
             "diagnostic_msgs", "rosgraph_msgs", "builtin_interfaces", "visualization_msgs",
             "nav_msgs", "trajectory_msgs", "rcl_interfaces"}

#: Subpackages (and top-level modules) that may import ROS.
ROS_SIDE = {"nodes", "cli"}


def _unit(module: str) -> str:
    """The subpackage (or top-level module) a dotted name of the package belongs to."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _imports(path: Path) -> list[str]:
    """Absolute names of everything ``path`` imports (module level and inside functions)."""
    rel = path.relative_to(PKG.parent).with_suffix("")
    package = list(rel.parts[:-1])
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            out.append(mod)
            out += [f"{mod}.{a.name}" for a in node.names]
    return out


def _graph() -> dict[str, dict[str, list[str]]]:
    """unit -> {imported unit or ROS root -> files that import it}."""
    graph: dict[str, dict[str, list[str]]] = {}
    for path in sorted(PKG.rglob("*.py")):
        src = _unit(".".join(path.relative_to(PKG.parent).with_suffix("").parts))
        edges = graph.setdefault(src, {})
        for name in _imports(path):
            root = name.split(".")[0]
            if root == "rheo_shaping":
                dst = _unit(name)
                known = (PKG / dst).is_dir() or (PKG / f"{dst}.py").is_file()
                if dst != src and known:
                    edges.setdefault(dst, []).append(path.name)
            elif root in ROS_ROOTS:
                edges.setdefault(root, []).append(path.name)
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as a path (first node repeated at the end), or None."""
    done: set[str] = set()

    def visit(node: str, path: list[str]) -> list[str] | None:
        if node in path:
            return path[path.index(node):] + [node]
        if node in done:
            return None
        for nxt in sorted(graph.get(node, ())):
            found = visit(nxt, path + [node])
            if found:
                return found
        done.add(node)
        return None

    for node in sorted(graph):
        found = visit(node, [])
        if found:
            return found
    return None


def test_core_imports_no_ros_and_no_nodes():
    bad = []
    for src, edges in _graph().items():
        if src in ROS_SIDE:
            continue
        for dst, files in edges.items():
            if dst in ROS_ROOTS or dst in ROS_SIDE:
                bad.append(f"{src} imports {dst} ({', '.join(sorted(set(files)))})")
    assert not bad, "the core must not import ROS or the nodes/cli: " + "; ".join(bad)


def test_subpackage_graph_is_acyclic():
    graph = {s: {d for d in e if d not in ROS_ROOTS and d != "__init__"}
             for s, e in _graph().items() if s != "__init__"}
    assert {"params", "sheet", "planning", "safety", "nodes"} <= set(graph)  # sees the tree
    assert graph["planning"] >= {"params", "sheet"}
    cycle = _cycle(graph)
    assert cycle is None, "import cycle between subpackages: " + " -> ".join(cycle)


def _module_graph() -> dict[str, set[str]]:
    """module -> the package's modules it imports (dotted names; a package is its
    ``__init__``).  An import of a module's own enclosing package is left out: that is how
    a module reaches its package's lazy API, which imports nothing until a name is used."""
    mods = {".".join(p.relative_to(PKG.parent).with_suffix("").parts).removesuffix(".__init__")
            for p in PKG.rglob("*.py")}
    graph = {}
    for path in sorted(PKG.rglob("*.py")):
        src = ".".join(path.relative_to(PKG.parent).with_suffix("").parts).removesuffix(
            ".__init__")
        graph[src] = {d for d in _imports(path)
                      if d in mods and d != src and not src.startswith(d + ".")}
    return graph


def test_module_graph_is_acyclic():
    """No two modules import each other, directly or round a loop (imports inside
    functions count: they are dependencies too, only later)."""
    graph = _module_graph()
    assert graph["rheo_shaping.planning.pieces"] >= {"rheo_shaping.planning.limits"}
    assert len(graph) > 100                                     # sees the whole tree
    cycle = _cycle(graph)
    assert cycle is None, "import cycle between modules: " + " -> ".join(cycle)


def test_the_cycle_check_finds_a_cycle():
    """The walk is not vacuous: a cycle is reported, a chain is not."""
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None


def test_top_level_import_is_cheap():
    code = ("import sys, rheo_shaping as rs; heavy = [m for m in ('numba', 'scipy', 'rclpy', "
            "'matplotlib') if m in sys.modules]; assert not heavy, heavy; "
            "assert callable(rs.run_movement) and callable(rs.load_cell); "
            "assert callable(rs.identify_paper) and callable(rs.diagnose)")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_docs_architecture_lists_every_import_between_subpackages():
    """docs/architecture.md's table ("may import") covers what the code imports."""
    import re
    doc = (PKG.parent / "docs" / "architecture.md").read_text()
    allowed: dict[str, set[str]] = {}
    for row in re.findall(r"^\| (`[^|]*`) \|[^|]*\| ([^|]*) \|$", doc, re.M):
        units = re.findall(r"`([a-z_]+)(?:/|\.py)?`", row[0])
        for unit in units:
            allowed[unit] = set(re.findall(r"`([a-z_]+)`", row[1].split("(")[0]))
    graph = _graph()
    missing = []
    for src in ("params", "material", "identification", "sheet", "planning", "records",
                "study", "safety", "diagnosis", "adaptive", "parallel", "units"):
        assert src in allowed, f"docs/architecture.md has no row for {src}"
        used = {d for d in graph.get(src, {}) if d not in ROS_ROOTS and d not in ("_lazy",)}
        missing += [f"{src} -> {d}" for d in sorted(used - allowed[src])]
    assert not missing, "imports docs/architecture.md does not list: " + ", ".join(missing)


def _lazy_packages() -> list[str]:
    """Every package of rheo_shaping whose ``__init__`` declares a lazy public API."""
    return sorted(".".join(p.parent.relative_to(PKG.parent).parts)
                  for p in PKG.rglob("__init__.py") if "lazy_api(" in p.read_text())


def test_every_lazy_public_name_resolves_to_its_definition():
    """Each name a package's ``__all__`` lists resolves, and is defined where the package
    says (a re-export from another module would be a second home for it)."""
    import importlib
    import inspect
    pkgs = _lazy_packages()
    assert {"rheo_shaping", "rheo_shaping.sheet", "rheo_shaping.planning",
            "rheo_shaping.safety", "rheo_shaping.adaptive"} <= set(pkgs)    # sees the tree
    bad = []
    for name in pkgs:
        pkg = importlib.import_module(name)
        assert pkg.__all__, f"{name} lists no public name"
        for attr in pkg.__all__:
            try:
                obj = getattr(pkg, attr)
            except (AttributeError, ImportError) as exc:
                bad.append(f"{name}.{attr}: {exc}")
                continue
            # a class or function names its defining module (a constant's type does not)
            home = obj.__module__ if inspect.isclass(obj) or inspect.isfunction(obj) else None
            if home is not None and not home.startswith(name):
                bad.append(f"{name}.{attr} is defined in {home}")
    assert not bad, "lazy public names that do not resolve: " + "; ".join(bad)


def _packages() -> list[str]:
    """Every package of rheo_shaping and of the validation (each folder with an
    ``__init__.py``), dotted."""
    return sorted(".".join(p.parent.relative_to(PKG.parent).parts)
                  for root in (PKG, VALIDATION) for p in root.rglob("__init__.py"))


def test_every_package_declares_its_public_api():
    """Each package's ``__init__`` declares ``__all__`` (read from the source: the ROS side
    is checked without rclpy), and in the core each name it lists resolves."""
    import importlib
    pkgs = _packages()
    assert {"rheo_shaping.diagnosis", "rheo_shaping.nodes", "rheo_shaping.cli",
            "rheo_shaping_validation.benchmark"} <= set(pkgs)
    bad = []
    for name in pkgs:
        init = PKG.parent / Path(*name.split(".")) / "__init__.py"
        tree = ast.parse(init.read_text())
        declared = any(isinstance(n, (ast.Assign, ast.AnnAssign)) and "__all__" in
                       ast.unparse(n.targets[0] if isinstance(n, ast.Assign) else n.target)
                       for n in tree.body)
        if not declared:
            bad.append(f"{name}: no __all__")
            continue
        if _unit(name) in ROS_SIDE:
            continue
        pkg = importlib.import_module(name)
        bad += [f"{name}.{attr} does not resolve" for attr in pkg.__all__
                if not hasattr(pkg, attr)]
    assert not bad, "packages without a public API: " + "; ".join(bad)


def test_the_diagnosis_public_face():
    """``from rheo_shaping.diagnosis import diagnose, Diagnosis, Verdict``: the verdict an
    enum whose values are the JSON's, the diagnosis frozen and built by keyword."""
    import dataclasses
    import enum
    from rheo_shaping.diagnosis import DEFAULTS, Diagnosis, Verdict, diagnose
    assert issubclass(Verdict, enum.StrEnum)
    assert {v.value for v in Verdict} == {"none", "effect", "pair", "measurement chain",
                                          "unexplained"}
    params = dataclasses.fields(Diagnosis)
    assert Diagnosis.__dataclass_params__.frozen
    assert all(f.kw_only for f in params)
    assert callable(diagnose) and DEFAULTS.floor == "model-form"


def test_the_product_imports_nothing_of_the_validation():
    """``rheo_shaping`` (what a cell runs) imports nothing from ``rheo_shaping_validation``
    (what it is measured with), at module level or inside functions; the validation imports
    no ROS and no node."""
    assert (VALIDATION / "benchmark" / "world.py").is_file()       # sees the validation
    bad = [f"{p.relative_to(PKG.parent)} imports {name}" for p in sorted(PKG.rglob("*.py"))
           for name in _imports(p) if name.split(".")[0] == VALIDATION.name]
    assert not bad, "the product imports the validation: " + "; ".join(bad)
    ros = [f"{p.relative_to(PKG.parent)} imports {name}" for p in sorted(VALIDATION.rglob("*.py"))
           for name in _imports(p) if name.split(".")[0] in ROS_ROOTS
           or name.startswith("rheo_shaping.nodes")]
    assert not ros, "the validation imports ROS: " + "; ".join(ros)
    assert any(name.startswith("rheo_shaping.diagnosis") for p in VALIDATION.rglob("*.py")
               for name in _imports(p))                           # the walk reads it
