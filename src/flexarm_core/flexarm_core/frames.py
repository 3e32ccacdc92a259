"""Names of the flexarm frames (one place for every node and message).

``base_link`` is the robot's root (REP 103: x forward, z up); the 3-D messages (``/tf``, the
scene's poses and markers) are in it. ``arm_plane`` is the arm's plane: ``base_link`` turned
about its x axis so that its x, y are the planar x, y_up of the flexarm messages and its z the
joints' axis (:data:`flexarm_core.plane.PLANE_IN_BASE`). A planar message
(``flexarm_msgs/TipPose``) names ``arm_plane``: a tf2 user then gets (x, y, 0) in it, the same
point as (x, 0, y) in ``base_link``. The state publisher puts ``arm_plane`` on ``/tf_static``.

``tip_link`` is the tool of the rigid model (the URDF's chain, flexarm_description.chain).
``tip_camera_calibrated`` is the tip camera where the tool calibration puts it, in
``tip_link``, beside the URDF's nominal ``tip_camera_link`` (the vision node publishes it on
``/tf_static``).
"""

BASE_FRAME = 'base_link'
PLANE_FRAME = 'arm_plane'
TIP_FRAME = 'tip_link'
CALIBRATED_CAMERA_FRAME = 'tip_camera_calibrated'
