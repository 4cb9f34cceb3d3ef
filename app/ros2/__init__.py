"""ROS 2 without ROS: the daemon's live data as ROS 2 topics over DDS (Eclipse Cyclone DDS through the
``cyclonedds`` binding), with ROS 2's naming (topic ``rt/<name>``, type ``<pkg>::msg::dds_::<Type>_``),
types (:mod:`app.ros2.msgs`), QoS profiles (:mod:`app.ros2.qos`) and REP 105 / REP 117 conventions
(:mod:`app.ros2.convert`); :mod:`app.ros2.publisher` runs it beside the control loop without ever
blocking it. Importing this package loads nothing from the binding."""
