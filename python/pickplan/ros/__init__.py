"""pickplan on a robot: a ROS 2 node that plans picks from depth cameras (``pickplan ros serve``).

Installed with the ``ros`` extra (``pip install 'pickplan[ros]'``: rclpy and the message packages
as wheels) or used from a sourced ROS 2 installation. Only ``node``, ``markers`` and ``client``
import rclpy and the messages; ``convert`` (ROS messages -> numpy, checked), ``pipeline`` (a
request -> a timed trajectory, the library's planning from depth) and ``extra`` import without it.
"""
