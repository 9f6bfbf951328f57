"""The wrist described for other tools: MJCF (MuJoCo; the physical emulator loads it) and URDF
(ROS: robot_state_publisher, RViz, Foxglove), generated from a profile's geometry and
``[plant]``. SI units (m, kg, rad) as both formats expect."""
