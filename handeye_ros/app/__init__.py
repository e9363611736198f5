"""The application: what the command-line tools and the node's worker share, above the core.

- :mod:`.request`: a :class:`~.request.Request` (two files, a bag, or the node's buffers) and
  :func:`~.request.run`, the one function under every front end; the options file.
- :mod:`.offline`: ``offline_calibrate`` (argparse -> Request), its command line in
  :mod:`.offline_options`; :mod:`.demo` its built-in example.
- :mod:`.replay`: a bag replayed through the node's own conversion and buffers.
- :mod:`.runs` and :mod:`.evaluate`: many recordings (a manifest, one run each) on Dask, and
  :mod:`.results_table` their table.
- :mod:`.rig`: one rig over many recordings (``--rig``, ``--shared-extrinsic``, the node's
  ``rig_file``); :mod:`.rig_file` the rig's file.
- :mod:`.commands`: the commands' names, for ``ros2 run`` and on a pip install's PATH.
- :mod:`.params_file`: the node's own options and the params file, which the offline tool reads
  too (hence here, below :mod:`handeye_ros.ros`).
"""
