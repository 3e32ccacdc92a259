"""What every flexarm node shares: its ``main()`` (Jazzy style, as in ros2/examples) and the
end of an action goal."""
from __future__ import annotations

from collections.abc import Callable

import rclpy
from rclpy.action.server import ServerGoalHandle
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.node import Node


def run(make_node: Callable[[], Node], args: list[str] | None = None,
        executor: Callable[[], Executor] | None = None) -> None:
    """Init rclpy, build the node, spin until Ctrl-C / SIGTERM / shutdown, clean up.

    A RuntimeError raised by a subscription take while SIGINT shuts the context down (an
    rclpy race) ends the node like the interrupt it is, with exit code 0.
    """
    rclpy.init(args=args)
    node = None
    try:
        node = make_node()
        if executor is None:
            rclpy.spin(node)
        else:
            spinner = executor()
            spinner.add_node(node)
            spinner.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:
        if rclpy.ok():
            raise
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


def finish_goal(handle: ServerGoalHandle, code: int, canceled_code: int) -> None:
    """End an action goal by its result code: 0 succeeds, ``canceled_code`` cancels, any
    other aborts (the control_msgs convention of an error code in the result)."""
    if code == 0:
        handle.succeed()
    elif code == canceled_code:
        handle.canceled()
    else:
        handle.abort()
