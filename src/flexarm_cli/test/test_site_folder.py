"""A site folder: its starting point, and its config/ layered over the clone's (parameter by
parameter, robot entries by name, topic remappings added), without a graph."""
import pytest

from flexarm_bringup import launcher
from flexarm_cli.site_folder import write_site
from flexarm_core import params


@pytest.fixture
def site(tmp_path, monkeypatch):
    folder = tmp_path / 'site'
    write_site(folder, 'bridge')
    monkeypatch.setattr(params, 'SITE_CONFIG_DIR', folder / 'config')
    return folder


def test_init_writes_a_commented_start_and_never_overwrites(tmp_path):
    folder = tmp_path / 'a'
    written = write_site(folder, 'ros2_control')
    assert {p.name for p in written} == {'graph.yaml', 'controllers.yaml', 'arm.yaml',
                                         'camera.yaml', 'vision.yaml'}
    assert all(line.startswith('#') or not line
               for line in (folder / 'config' / 'camera.yaml').read_text().splitlines())
    (folder / 'config' / 'arm.yaml').write_text('# mine\n')
    with pytest.raises(FileExistsError, match='nothing was written'):
        write_site(folder, 'ros2_control')
    assert (folder / 'config' / 'arm.yaml').read_text() == '# mine\n'
    with pytest.raises(ValueError, match='bridge, ros2_control'):
        write_site(tmp_path / 'b', 'sim')


def test_the_site_sets_what_it_names_and_the_clone_the_rest(site):
    bridge = site / 'config' / 'bridge.yaml'
    bridge.write_text(bridge.read_text().replace('47800', '47999'))
    values = params.load_config('bridge.yaml', node_name='flexarm_bridge')
    assert values['port'] == 47999 and values['retry_min'] == 0.2        # the clone's
    assert params.config_layers('sim.yaml') == [params.config_path('sim.yaml')]   # none there


def test_the_site_graph_replaces_its_robot_and_remaps_the_camera(site):
    graph = site / 'config' / 'graph.yaml'
    graph.write_text(graph.read_text().replace(
        'camera/image_raw: camera/image_raw', 'camera/image_raw: /site_camera/image'))
    assert launcher.robot_settings('bridge')['use_sim_time'] is False
    vision = next(s for s in launcher.load_graph('bridge') if s.name == 'flexarm_vision')
    command = launcher.node_command(vision)
    assert command[command.index('camera/image_raw:=/site_camera/image') - 1] == '-r'
    files = [command[i + 1] for i, word in enumerate(command) if word == '--params-file']
    assert files[-1] == str(site / 'config' / 'vision.yaml')           # the site's last
    assert [s.name for s in launcher.load_graph('sim')][0] == 'flexarm_sim'   # the clone's
