"""The ROS 2 front end (rclpy): the calibrator node (:mod:`.node`, started by :mod:`.calibrator`),
the answers of its calls that wait or are refused (:mod:`.calls`), its pose topics
(:mod:`.subscriptions`, :mod:`.types`), parameters (:mod:`.parameters`), latched result outputs
(:mod:`.outputs`), the files it writes, only inside ``output_dir`` (:mod:`.files`), diagnostics
(:mod:`.diagnostics`), readiness status (:mod:`.status`, the streams' clocks in :mod:`.clocks`)
and auto mode (:mod:`.auto_mode`), which read the node through :mod:`.host`'s Protocol, its worker processes (:mod:`.worker`, :mod:`.jobs`), the
start and stop they share (:mod:`.lifecycle`), sim_publisher (its options in
:mod:`.sim_options`) and publish_calibration."""
