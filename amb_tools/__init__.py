"""
amb_tools: the ROS glue the parts share (imports only amb_common, amb_msgs and rclpy).

``streams`` (QoS), ``conversions`` (arrays <-> messages), ``cdr`` (serialisation in numpy),
``validation``, ``node_main`` (a node's main), ``recorder_node``, ``replay_bridge``, and the
bags: ``bag_writer``, ``bag_types``, ``bag_read``.
"""
