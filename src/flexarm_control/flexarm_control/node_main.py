"""The ``main()`` every flexarm node shares (Jazzy style, as in ros2/examples)."""
from __future__ import annotations

from collections.abc import Callable

import rclpy
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
