"""The shaping cell: simulator, planner and monitor (and RViz, the gap watch) from one params
file.

    ros2 launch rheo_shaping cell.launch.py
    ros2 launch rheo_shaping cell.launch.py namespace:=/cell2 rviz:=true
    ros2 launch rheo_shaping cell.launch.py params_file:=my_cell.yaml use_sim_time:=false
    ros2 launch rheo_shaping cell.launch.py managed:=true namespace:=/cellA
    ros2 launch rheo_shaping cell.launch.py namespace:=/cellB clock_topic:=clock

Arguments (docs/ros.md, "Launch"):

* ``params_file``: the cell in ``/**``, node settings in ``/**/simulator``,
  ``/**/planner``, ``/**/monitor`` (default: the package's config/cell.yaml);
* ``namespace``: every node, topic and service of the cell moves there; the clock
  stays the absolute ``/clock`` (and the cake frame goes on the absolute ``/tf_static``),
  where rviz2, ``ros2 bag`` and rqt find them without remaps;
* ``clock_topic``: ``/clock`` (default) or ``clock``: the cell's clock in its namespace
  (``-r /clock:=clock`` on every node, the simulator's publisher included), for several
  simulated cells on one ROS domain;
* ``use_sim_time``: ``true`` (default) the simulator is the clock (its
  ``real_time_factor`` from the file) and planner and monitor follow it;
  ``false``: everything on the wall clock, the simulator at real time;
* ``rviz``: ``true`` also starts RViz with the package's rviz/cell.rviz;
* ``managed``: ``true`` starts the managed (lifecycle) nodes ``simulator_managed``,
  ``monitor_managed``, ``planner_managed`` (node names simulator, monitor, planner; with
  ``gap_watch``, ``gap_watch_managed`` too) and the ``lifecycle_manager`` with those
  ``node_names``, which brings them up in order and down to a safe state when one fails
  (docs/ros.md, "Managed start-up");
* ``gap_watch``: ``true`` also starts the gap watch (the model beside the cell,
  docs/gapwatch.md), its settings from ``/**/gap_watch`` of the params file;
* ``adaptive``: ``true`` the planner's closed loop (its ``adaptive`` parameter: it learns
  the batch's material while it shapes and re-plans the rest, docs/closed-loop.md).

Values given here reach the nodes as ``-p`` on their command line, which beats the
params file's node sections (rheo_shaping/nodes/ros_params.py).
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

PACKAGE = 'rheo_shaping'
#: Where the simulator's clock goes (rheo_shaping.nodes.topics.CLOCK_TOPICS; not imported
#: here: the launch file needs no ROS message package).
CLOCK_TOPICS = ('/clock', 'clock')


def _nodes(context):
    share = get_package_share_directory(PACKAGE)
    params_file = LaunchConfiguration('params_file').perform(context)
    namespace = LaunchConfiguration('namespace').perform(context)
    sim_time = LaunchConfiguration('use_sim_time').perform(context).lower() in ('true', '1')
    follow = ['-p', f"use_sim_time:={'true' if sim_time else 'false'}"]
    simulator_args = [] if sim_time else ['-p', 'real_time_factor:=1.0',
                                          '-p', 'publish_clock:=false']
    adaptive = LaunchConfiguration('adaptive').perform(context).lower() in ('true', '1')
    planner_args = follow + (['-p', 'adaptive:=true'] if adaptive else [])
    clock_topic = LaunchConfiguration('clock_topic').perform(context)
    if clock_topic not in CLOCK_TOPICS:
        raise RuntimeError(f"clock_topic:={clock_topic!r}: expected one of "
                           f"{', '.join(CLOCK_TOPICS)} (/clock: the absolute clock rviz2 and "
                           f"ros2 bag read; clock: the cell's namespace)")
    # every node of the cell, the simulator's publisher and each time source alike
    clock = [('/clock', 'clock')] if clock_topic == 'clock' else []
    common = dict(package=PACKAGE, namespace=namespace, parameters=[params_file],
                  output='screen', emulate_tty=True, remappings=clock)
    gap_watch = LaunchConfiguration('gap_watch').perform(context).lower() in ('true', '1')
    if LaunchConfiguration('managed').perform(context).lower() in ('true', '1'):
        names = ['simulator', 'monitor', 'planner'] + (['gap_watch'] if gap_watch else [])
        cell = [
            Node(executable='simulator_managed', name='simulator',
                 ros_arguments=simulator_args, **common),
            Node(executable='monitor_managed', name='monitor', ros_arguments=follow,
                 **common),
            Node(executable='planner_managed', name='planner', ros_arguments=planner_args,
                 **common),
            Node(executable='gap_watch_managed', name='gap_watch', ros_arguments=follow,
                 condition=IfCondition(LaunchConfiguration('gap_watch')), **common),
            # the nodes above it manages; the cell's clock: one stamp source
            Node(executable='lifecycle_manager', name='lifecycle_manager',
                 ros_arguments=follow + ['-p', f"node_names:=[{','.join(names)}]"],
                 **common),
        ]
    else:
        cell = [
            Node(executable='simulator', name='simulator', ros_arguments=simulator_args,
                 **common),
            Node(executable='monitor', name='monitor', ros_arguments=follow, **common),
            Node(executable='planner', name='planner', ros_arguments=planner_args,
                 **common),
            Node(executable='gap_watch', name='gap_watch', ros_arguments=follow,
                 condition=IfCondition(LaunchConfiguration('gap_watch')), **common),
        ]
    return cell + [
        Node(package='rviz2', executable='rviz2', name='rviz2', namespace=namespace,
             arguments=['-d', os.path.join(share, 'rviz', 'cell.rviz')],
             parameters=[{'use_sim_time': sim_time}], remappings=clock, output='screen',
             condition=IfCondition(LaunchConfiguration('rviz'))),
    ]


def generate_launch_description():
    share = get_package_share_directory(PACKAGE)
    return LaunchDescription([
        DeclareLaunchArgument(
            'params_file', default_value=os.path.join(share, 'config', 'cell.yaml'),
            description='params file: the cell in /**, node settings in /**/<node>'),
        DeclareLaunchArgument(
            'namespace', default_value='',
            description='ROS namespace of the whole cell (e.g. /cell2); empty: the root'),
        DeclareLaunchArgument(
            'use_sim_time', default_value='true',
            description='true: the simulator is the clock; false: wall clock, real time'),
        DeclareLaunchArgument(
            'clock_topic', default_value='/clock', choices=list(CLOCK_TOPICS),
            description="/clock: the absolute clock rviz2 and ros2 bag read; clock: the "
                        "cell's own in its namespace (several simulated cells on one domain)"),
        DeclareLaunchArgument(
            'rviz', default_value='false', description='true: start RViz with rviz/cell.rviz'),
        DeclareLaunchArgument(
            'managed', default_value='false',
            description='true: the managed (lifecycle) nodes and the lifecycle_manager'),
        DeclareLaunchArgument(
            'gap_watch', default_value='false',
            description='true: also start the gap watch (the model beside the cell)'),
        DeclareLaunchArgument(
            'adaptive', default_value='false',
            description="true: the planner's closed loop (learns the batch, re-plans)"),
        OpaqueFunction(function=_nodes),
    ])
