"""One owner per stream (rheo_shaping.safety.owners.StreamOwner): the bound writer of the
owner's name only; any other writer makes the stream untrusted, named once it has a name."""
from __future__ import annotations

from rheo_shaping.safety.command_gate import UNNAMED, Publisher
from rheo_shaping.safety.owners import StreamOwner, owner_name

MON = Publisher("/cell/monitor", "aa.01")
ROGUE = Publisher("/rogue", "bb.02")
TWIN = Publisher("/cell/monitor", "cc.03")


def test_owner_names_in_a_namespace_and_the_root():
    assert owner_name("/cell", "monitor") == "/cell/monitor"
    assert owner_name("/", "monitor") == "/monitor"


def test_binds_to_the_owner_and_refuses_any_second_writer_by_name():
    s = StreamOwner("/cell/shaping/checked", "/cell/monitor")
    assert s.judge([MON]).trusted and s.bound == MON
    t = s.judge([MON, ROGUE])
    assert not t.trusted and t.foreign == (ROGUE,)
    assert t.reason.startswith("a second writer of /cell/shaping/checked: /rogue (bb.02)")
    assert s.report_once(t) and not s.report_once(t)          # reported once
    # a second node of the owner's own name is foreign too once one is bound (by GID)
    t = s.judge([MON, TWIN])
    assert not t.trusted and t.foreign == (TWIN,)
    assert s.judge([MON]).trusted                               # the rogue left


def test_a_writer_without_a_name_yet_is_not_trusted_but_not_named():
    s = StreamOwner("/t", "/monitor")
    nameless = Publisher(f"_NODE_NAMESPACE_UNKNOWN_/{UNNAMED}", "dd")
    t = s.judge([Publisher("/monitor", "aa"), nameless])
    assert s.bound is not None and not t.trusted and t.foreign == ()
    assert "whose node the graph does not name yet" in t.reason


def test_unbound_streams_are_not_trusted_and_a_rogue_alone_never_binds():
    s = StreamOwner("/t", "/monitor")
    t = s.judge([ROGUE])
    assert not t.trusted and s.bound is None and t.foreign == (ROGUE,)
    assert "no writer of /t named /monitor" in t.reason
    t = s.judge([Publisher("/monitor", "a"), Publisher("/monitor", "b")])
    assert not t.trusted and s.bound is None and "2 writers of /t named /monitor" in t.reason
    assert not s.judge([]).trusted


def test_a_restarted_owner_is_bound_again_and_its_count_starts_afresh():
    s = StreamOwner("/t", "/cell/monitor")
    assert s.judge([MON]).trusted and s.accept(5) and s.accept(6)
    assert not s.accept(6) and not s.accept(2)                  # not the bound writer's count
    again = Publisher("/monitor", "ee.09")
    s2 = StreamOwner("/t", "/monitor")
    s2.judge([Publisher("/monitor", "aa")])
    assert s2.accept(100)
    assert s2.judge([again]).trusted and s2.bound == again      # the old writer left
    assert s2.accept(1)                                         # its own count from 1
    assert s.accept(0)                                          # no number: not judged


def test_by_name_only_a_restarted_owner_beats_beside_the_killed_ones_writer():
    """A heartbeat is taken from any writer of the node's name (a restarted node's writer
    while the killed one's stays in the graph for its lease), never from another name."""
    s = StreamOwner("/monitor/heartbeat", "/monitor", strict=False)
    old, new = Publisher("/monitor", "aa"), Publisher("/monitor", "bb")
    assert s.judge([old, new]).trusted and s.judge([new]).trusted
    t = s.judge([new, ROGUE])
    assert not t.trusted and t.foreign == (ROGUE,)
    assert not s.judge([]).trusted
