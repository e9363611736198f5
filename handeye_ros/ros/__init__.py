"""The ROS 2 front end (rclpy): the calibrator node (:mod:`.node`, started by :mod:`.calibrator`),
its parameters (:mod:`.parameters`) and diagnostics (:mod:`.diagnostics`), sim_publisher and
publish_calibration."""
