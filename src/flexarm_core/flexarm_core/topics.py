"""Names of the flexarm graph's topics, actions and services (one place for every node).

The controller contract is ros2_control's: joint_state_broadcaster's ``joint_states`` and
joint_trajectory_controller's, either its ``follow_joint_trajectory`` action (a ros2_control
arm: accepted or rejected, with a result) or its ``joint_trajectory`` topic (the simulator).
forward_command_controller's ``forward_position_controller/commands`` (one set-point per move)
is only the bridge's (config/graph.yaml ``robot_settings``: ``motion.joint_commands``).

Names are relative, so one arm's graph runs under a namespace (``flexarm up --namespace
arm1``: ``/arm1/joint_states``, ``/arm1/move_to_pose``, ...) and several arms share a ROS
domain; without a namespace they are the absolute names of before (``/joint_states``). Two
stay global: ``/clock`` (one simulated clock per domain) and ``/diagnostics`` (one health
stream per domain, as rqt_robot_monitor and Foxglove read it; a status names its node with its
namespace, ``arm1/flexarm_sim: controller``). ``tf``/``tf_static`` are namespaced like the
rest (the multi-robot convention of nav2: remap ``/tf:=tf`` for a viewer of one arm).
"""

JOINT_STATES = 'joint_states'                               # sensor_msgs/JointState
JOINT_COMMANDS = 'forward_position_controller/commands'     # std_msgs/Float64MultiArray
JOINT_TRAJECTORY = ('joint_trajectory_controller/'                # trajectory_msgs/
                    'joint_trajectory')                         # JointTrajectory
FOLLOW_JOINT_TRAJECTORY = ('joint_trajectory_controller/'         # control_msgs/action/
                           'follow_joint_trajectory')             # FollowJointTrajectory
CLOCK = '/clock'                                            # rosgraph_msgs/Clock
CAMERA_IMAGE = 'camera/image_raw'                           # sensor_msgs/Image (mono8)
CAMERA_INFO = 'camera/camera_info'                          # sensor_msgs/CameraInfo, latched
TIP_POSE = 'tip_pose'                                       # flexarm_msgs/TipPose
TIP_POSE_TRUTH = 'sim/tip_pose_truth'                       # flexarm_msgs/TipPose, evaluation only
SAMPLES = 'learner/samples'                                 # flexarm_msgs/DeflectionSample
MODEL = 'learner/model'                                     # flexarm_msgs/ModelInfo, latched
OUTCOMES = 'compensator/outcomes'                           # flexarm_msgs/GoalOutcome
ACTIVE_MODEL = 'compensator/active_model'                   # flexarm_msgs/ModelInfo, latched
MODEL_HEALTH = 'compensator/model_health'                   # flexarm_msgs/ModelHealth, latched
PAYLOAD = 'payload'                                         # std_msgs/Float64 [kg], latched

# Visible in rviz and Foxglove (flexarm_description; the compensator publishes the goal poses).
ROBOT_DESCRIPTION = 'robot_description'                     # std_msgs/String (URDF), latched
TF = 'tf'                                                   # tf2_msgs/TFMessage
TF_STATIC = 'tf_static'                                     # tf2_msgs/TFMessage, latched
TARGET_POSE = 'scene/target_pose'                           # geometry_msgs/PoseStamped
COMMANDED_POSE = 'scene/commanded_pose'                     # geometry_msgs/PoseStamped (x*)
MEASURED_TIP = 'scene/measured_tip'                         # geometry_msgs/PoseStamped
TRUE_TIP = 'scene/true_tip'                                 # geometry_msgs/PoseStamped, sim
SCENE_MARKERS = 'scene/markers'                             # visualization_msgs/MarkerArray
DIAGNOSTICS = '/diagnostics'                                # diagnostic_msgs/DiagnosticArray

MOVE_TO_POSE = 'move_to_pose'                               # flexarm_msgs/action/MoveToPose
COLLECT_SAMPLES = 'collect_samples'                         # flexarm_msgs/action/CollectSamples
TRAIN = 'train'                                             # flexarm_msgs/srv/Train
USE_MODEL = 'learner/use_model'                             # flexarm_msgs/srv/UseModel
REFRESH_MODEL = 'learner/refresh'                           # flexarm_msgs/action/RefreshModel

# The arm's one owner (flexarm_motion.ros.arm_owner_node): every motion claims the arm here.
ARM_MOTION = 'arm/motion'                                   # flexarm_msgs/ArmMotion, latched
CLAIM_ARM = 'arm/claim'                                     # flexarm_msgs/srv/ClaimArm
RELEASE_ARM = 'arm/release'                                 # flexarm_msgs/srv/ReleaseArm


def absolute(name: str, namespace: str = '') -> str:
    """The full name of ``name`` in ``namespace`` ('' or '/': the root): ``/arm1/tip_pose``."""
    if name.startswith('/'):
        return name
    namespace = namespace.strip('/')
    return f'/{namespace}/{name}' if namespace else f'/{name}'
