"""A site folder's starting point (``flexarm site init DIR --robot bridge|ros2_control``): what
a site sets for its own arm and camera, outside the clone (:mod:`flexarm_core.paths`).

The folder holds ``config/``, whose files layer over the clone's of the same name (parameter
by parameter; its ``graph.yaml`` replaces robot entries and settings by name and adds topic
remappings), and, once the graph runs, the site's state: ``calibration/``, ``data/``,
``models/``, ``runs/``, ``bags/``, ``results/``. Every file written here is commented: what a
site sets, and where the clone's default is. The params files other than the robot's start
empty of parameters (only comments), so the clone's defaults hold until the site sets one.
"""
from __future__ import annotations

from pathlib import Path

from flexarm_core.parameter_schema import node_schema
from flexarm_core.params import config_path

ROBOTS = ('bridge', 'ros2_control')

GRAPH = {
    'bridge': '''\
# The site's layer over the clone's config/graph.yaml (flexarm up --site DIR --robot bridge):
# robot entries and robot_settings here replace the clone's of the same name.
robot_settings:
  # A real arm runs on wall time: no node waits for a /clock.
  bridge: {use_sim_time: false, sim_clock: false, motion.joint_commands: forward}

robots:
  bridge:
    - name: flexarm_bridge
      role: bridge
      module: flexarm_bridge.bridge_node
      params_files: [arm.yaml, bridge.yaml]
      robot_parameters: [use_sim_time]
      restart: true
    # Your camera driver, if flexarm up should start it too (else start it yourself, in the
    # same ROS domain: flexarm ps shows the domain), e.g.:
    # - name: site_camera
    #   role: camera
    #   module: your_camera_driver.node
    #   params_files: [camera_driver.yaml]
    #   restart: true

# Topics, per node: the vision node reads camera/image_raw and camera/camera_info (relative:
# under the arm's namespace); remap them to your driver's.
remappings:
  flexarm_vision:
    camera/image_raw: camera/image_raw
    camera/camera_info: camera/camera_info
''',
    'ros2_control': '''\
# The site's layer over the clone's config/graph.yaml (flexarm up --site DIR --robot
# ros2_control): robot entries and robot_settings here replace the clone's of the same name.
# The controller manager (ros2_control_node with this folder's config/controllers.yaml) and
# the camera driver are started by you, first, in the domain flexarm up then joins
# (flexarm up --domain-id N, or ROS_DOMAIN_ID exported in both shells); flexarm starts no
# controller of its own. docs/connecting-your-arm.md walks through it.
robot_settings:
  ros2_control: {use_sim_time: false, sim_clock: false,
                 motion.joint_commands: follow_joint_trajectory}

robots:
  ros2_control: []

# Topics, per node: the vision node reads camera/image_raw and camera/camera_info (relative:
# under the arm's namespace); remap them to your driver's.
remappings:
  flexarm_vision:
    camera/image_raw: camera/image_raw
    camera/camera_info: camera/camera_info
''',
}

BRIDGE = '''\
# The controller link of this site (layered over the clone's config/bridge.yaml; the protocol:
# src/flexarm_bridge/PROTOCOL.md).
/**:
  ros__parameters:
    host: {host}           # your controller's address (127.0.0.1: a rehearsal on this machine)
    port: {port}               # its TCP port
    link_key_file: ''         # the site key (flexarm keygen FILE): required off this machine
'''

# Params files whose every parameter a site may set: written as comments of the clone's.
COMMENTED = ('arm.yaml', 'camera.yaml', 'vision.yaml')


def commented(name: str) -> str:
    """The clone's ``config/<name>`` with every line a comment: a site uncomments what it
    sets (and the section keys above it)."""
    text = config_path(name).read_text(encoding='utf-8')
    lines = [f'# {line}' if line.strip() else '' for line in text.splitlines()]
    return (f'# The site\'s layer over the clone\'s config/{name}: uncomment what this site '
            'sets,\n# with the keys above it; the rest stays the clone\'s.\n'
            + '\n'.join(lines) + '\n')


def files(robot: str) -> dict[str, str]:
    """Relative path -> text of every file of a site folder for ``robot``."""
    if robot not in ROBOTS:
        raise ValueError(f'robot must be one of {", ".join(ROBOTS)}, got {robot!r}')
    out = {'config/graph.yaml': GRAPH[robot]}
    if robot == 'bridge':
        shipped = node_schema(config_path('bridge.yaml'), 'flexarm_bridge')   # the clone's
        out['config/bridge.yaml'] = BRIDGE.format(host=shipped['host'].default,
                                                  port=shipped['port'].default)
    else:
        out['config/controllers.yaml'] = commented('controllers.yaml')
    out.update({f'config/{name}': commented(name) for name in COMMENTED})
    return out


def write_site(folder: Path, robot: str) -> list[Path]:
    """Write the starting point into ``folder`` (made if missing); FileExistsError, and
    nothing written, if any of its files exists: a site's own settings are never overwritten."""
    wanted = {folder / rel: text for rel, text in files(robot).items()}
    taken = [str(path) for path in wanted if path.exists()]
    if taken:
        raise FileExistsError(f'{", ".join(taken)} exist already; nothing was written')
    for path, text in wanted.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding='utf-8')
    return list(wanted)
