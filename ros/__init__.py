"""A run in ROS 2 tools: :func:`~pushtrain.ros.bag.export_bag` writes a run folder as a rosbag2
folder (``metadata.yaml`` and one MCAP file of standard ROS 2 messages) that ``ros2 bag``, RViz
and Foxglove open. The bag is written with ``rosbags`` (PyPI), the only module that imports it.
"""

__all__: list[str] = []
