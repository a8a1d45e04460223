"""The cell's SROS2 access-control policy, read from the graph of a running cell
(docs/safety.md, "Access control").

What ``ros2 security generate_policy`` (ros2/sros2, ``verb/generate_policy.py``) does, for
the cell's nodes only and without the sros2 package (it has no wheel here): for each node
of the cell, one enclave ``/rheo_shaping/<node>`` with one profile that ALLOWs exactly the
topics it publishes and subscribes to and the services it serves and calls, as the graph
shows them; names relative to the node's namespace, ``~`` for its own (sros2's rules).  The
policy's format is sros2's ``policy.xsd`` (version 0.2.0).  With a Jazzy installation that
has the security plugins, ``ros2 security create_permission`` turns it into each enclave's
signed permissions::

    python -m rheo_shaping.nodes.policy --out cell_policy.xml [--namespace /cellA]

(start the cell first: ``rheo-shaping cell`` or the launch file, managed for the lifecycle
services).  The shipped policy, ``config/sros2/cell_policy.xml``, is the managed cell's with
the gap watch; ``test/nodes/test_security_policy.py`` checks it against the running cells.
"""
from __future__ import annotations

import argparse
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

#: The cell's nodes: an enclave each.
CELL_NODE_NAMES: tuple[str, ...] = ("simulator", "monitor", "planner", "lifecycle_manager",
                                    "gap_watch")
#: The enclave of each node (``--ros-args --enclave``): ``/rheo_shaping/<node>``.
ENCLAVE_ROOT = "/rheo_shaping"
POLICY_VERSION = "0.2.0"
#: (the permission kind, its rule, the graph query by node) in sros2's order
RULES = (("topic", "subscribe", "get_subscriber_names_and_types_by_node"),
         ("topic", "publish", "get_publisher_names_and_types_by_node"),
         ("service", "reply", "get_service_names_and_types_by_node"),
         ("service", "request", "get_client_names_and_types_by_node"))


def expression(fqn: str, node: str, ns: str) -> str:
    """A graph name as sros2 writes it in a node's profile: ``~/x`` for the node's own,
    relative to its namespace, else absolute."""
    node_fqn = ns.rstrip("/") + "/" + node
    if fqn.startswith(node_fqn + "/"):
        return "~" + fqn[len(node_fqn):]
    if fqn.startswith(ns.rstrip("/") + "/") and ns != "/":
        return fqn[len(ns.rstrip("/") + "/"):]
    if ns == "/" and fqn.startswith("/"):
        return fqn[1:]
    return fqn


def graph_policy(graph, nodes: dict[str, str]) -> ET.Element:
    """The policy of ``nodes`` (name -> namespace) as ``graph`` (an rclpy node) shows them."""
    policy = ET.Element("policy", version=POLICY_VERSION)
    enclaves = ET.SubElement(policy, "enclaves")
    for name, ns in nodes.items():
        enclave = ET.SubElement(enclaves, "enclave", path=f"{ENCLAVE_ROOT}/{name}")
        profile = ET.SubElement(ET.SubElement(enclave, "profiles"), "profile", ns=ns,
                                node=name)
        for kind, rule, query in RULES:
            names = sorted({expression(fqn, name, ns)
                            for fqn, _ in getattr(graph, query)(name, ns)})
            if names:
                group = ET.SubElement(profile, f"{kind}s", {rule: "ALLOW"})
                for n in names:
                    ET.SubElement(group, kind).text = n
    return policy


def settled_policy(graph, nodes: dict[str, str], spin_once, settle_s: float = 2.0,
                   timeout_s: float = 30.0) -> ET.Element:
    """:func:`graph_policy` once it has not changed for ``settle_s`` [s] of wall time (the
    nodes' endpoints are discovered one by one), or at ``timeout_s`` [s].  ``spin_once()``
    spins the executor of ``graph`` a little."""
    end = time.monotonic() + timeout_s
    last, since = None, time.monotonic()
    while True:
        policy = graph_policy(graph, nodes)
        seen = allowed(policy)
        now = time.monotonic()
        if seen != last:
            last, since = seen, now
        elif now - since >= settle_s or now > end:
            return policy
        spin_once()


def allowed(policy: ET.Element) -> dict[tuple[str, str], set[str]]:
    """What a policy allows: (node, rule) -> the names (``publish``, ``subscribe``,
    ``reply``, ``request``)."""
    out: dict[tuple[str, str], set[str]] = {}
    for profile in policy.iter("profile"):
        for group in profile:
            for rule, value in group.attrib.items():
                if value == "ALLOW":
                    out.setdefault((profile.attrib["node"], rule), set()).update(
                        e.text or "" for e in group)
    return out


def dump(policy: ET.Element) -> str:
    """The policy as sros2 writes it (indented XML with its declaration)."""
    ET.indent(policy, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(policy, "unicode") + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m rheo_shaping.nodes.policy",
        description="Write the SROS2 policy of a running cell's nodes (what each publishes, "
                    "subscribes to, serves and calls, from the graph), as ros2 security "
                    "generate_policy does.")
    ap.add_argument("--out", type=Path, required=True, help="the policy file to write")
    ap.add_argument("--namespace", default="/", help="the cell's namespace (default /)")
    ap.add_argument("--nodes", default=",".join(CELL_NODE_NAMES),
                    help="the cell's nodes (comma-separated; those not running are left "
                         "out)")
    ap.add_argument("--wait", type=float, default=10.0,
                    help="seconds to wait for the nodes to appear in the graph")
    ap.add_argument("--force", action="store_true", help="overwrite an existing --out")
    args = ap.parse_args(argv)
    if args.out.exists() and not args.force:
        print(f"error: --out {args.out} exists: expected a new file (or --force)",
              file=sys.stderr)
        return 2
    import rclpy
    rclpy.init()
    try:
        graph = rclpy.create_node("rheo_shaping_policy_reader")
        wanted = [n for n in args.nodes.split(",") if n]
        end = time.monotonic() + args.wait
        found: dict[str, str] = {}
        while time.monotonic() < end:
            rclpy.spin_once(graph, timeout_sec=0.2)
            found = {n: ns for n, ns in graph.get_node_names_and_namespaces()
                     if n in wanted and ns == args.namespace}
            if len(found) == len(wanted):
                break
        if not found:
            print(f"error: none of the nodes {wanted} in namespace {args.namespace} within "
                  f"{args.wait:g} s: start the cell first", file=sys.stderr)
            return 1
        policy = settled_policy(graph, found, lambda: rclpy.spin_once(graph, timeout_sec=0.1))
        args.out.write_text(dump(policy))
        print(f"{args.out}: {', '.join(found)} ({len(found)} of {len(wanted)} nodes)")
        return 0
    finally:
        rclpy.try_shutdown()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
