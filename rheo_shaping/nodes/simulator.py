"""The ``simulator`` node: simulates the shaping cell (sheet, mould, tool) and publishes its state.

SCAFFOLD, to be filled by the ROS-cell work: for now it is only a real rclpy
node named ``simulator`` that spins until SIGINT (or an external shutdown) and
then exits with code 0, in the style of ros2/demos demo_nodes_py.
"""
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node


class SimulatorNode(Node):
    """Scaffold of the simulator node (no publishers, subscriptions or timers yet)."""

    def __init__(self):
        super().__init__('simulator')
        self.get_logger().info('simulator scaffold up')


def main(args=None):
    rclpy.init(args=args)
    node = SimulatorNode()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
