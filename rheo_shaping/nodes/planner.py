"""The ``planner`` node: plans jerk-limited tool trajectories for the shaping cell.

SCAFFOLD, to be filled by the ROS-cell work: for now it is only a real rclpy
node named ``planner`` that spins until SIGINT (or an external shutdown) and
then exits with code 0, in the style of ros2/demos demo_nodes_py.
"""
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node


class PlannerNode(Node):
    """Scaffold of the planner node (no publishers, subscriptions or timers yet)."""

    def __init__(self):
        super().__init__('planner')
        self.get_logger().info('planner scaffold up')


def main(args=None):
    rclpy.init(args=args)
    node = PlannerNode()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
