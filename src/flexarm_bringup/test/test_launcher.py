"""Node process specs and environments of the orchestrator, and how nodes are stopped."""
import os
import secrets
import signal
import subprocess
import sys
import textwrap
import time

import pytest
import yaml

from flexarm_bringup.launcher import (
    NodeProcess,
    NodeSpec,
    all_nodes,
    controllers,
    load_graph,
    node_command,
    node_name,
    ros_env,
    write_overrides,
)
from flexarm_core.dds_shm import SHM_DIR
from flexarm_core.params import config_path


def test_node_command_names_the_node_and_its_params(tmp_path) -> None:
    spec = NodeSpec(name='n', module='pkg.mod', params_files=('arm.yaml',),
                    parameters={'use_sim_time': True, 'rate': 2.5})
    overrides = write_overrides(spec, {'topics': ['/a', '/b'], 'rate': 3.0}, tmp_path / 'n.yaml')
    cmd = node_command(spec, overrides)
    assert cmd[:5] == [sys.executable, '-m', 'pkg.mod', '--ros-args', '-r']
    assert cmd[5] == '__node:=n'
    files = [cmd[i + 1] for i, a in enumerate(cmd) if a == '--params-file']
    assert files == [str(config_path('arm.yaml')), str(overrides)]
    assert yaml.safe_load(overrides.read_text()) == {'/**/n': {'ros__parameters': {
        'use_sim_time': True, 'rate': 3.0, 'topics': ['/a', '/b']}}}
    assert write_overrides(NodeSpec(name='m', module='x'), None, tmp_path / 'm.yaml') is None


def test_run_parameters_win_over_node_specific_config_entries(tmp_path) -> None:
    """rcl gives a node-specific params-file entry precedence over ``-p``; ours come last."""
    import rclpy
    from rclpy.context import Context

    spec = {s.name: s for s in load_graph('sim')}['flexarm_learner']
    overrides = write_overrides(spec, {'data_directory': '/elsewhere'}, tmp_path / 'l.yaml')
    context = Context()
    rclpy.init(context=context, args=node_command(spec, overrides)[3:], domain_id=0)
    try:
        node = rclpy.create_node('flexarm_learner', context=context,
                                 automatically_declare_parameters_from_overrides=True)
        assert node.get_parameter('data_directory').value == '/elsewhere'
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_ros_env_isolates_the_domain_and_drops_a_bootstrap_guard_without_its_path() -> None:
    env = ros_env(42, base={'_ROS_WHEELS_BOOTSTRAP_COMPLETE': '1', 'PATH': '/bin'})
    assert env['ROS_DOMAIN_ID'] == '42'
    assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
    assert '_ROS_WHEELS_BOOTSTRAP_COMPLETE' not in env
    assert env['PATH'] == '/bin'
    crash = subprocess.run([sys.executable, '-c', 'import ctypes; ctypes.string_at(0)'],
                           env=ros_env(42), capture_output=True, text=True, timeout=30)
    assert crash.returncode == -11                       # a node's crash names where it was
    assert 'Segmentation fault' in crash.stderr and 'line 1' in crash.stderr, crash.stderr
    widened = ros_env(42, base={'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET'})
    assert widened['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'    # only when asked for
    assert ros_env(42, discovery='SUBNET')['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'SUBNET'
    with pytest.raises(ValueError, match='discovery range'):
        ros_env(42, discovery='EVERYWHERE')


def test_a_child_with_the_bootstrappers_path_starts_once_and_one_without_it_twice() -> None:
    """ros-wheels-bootstrapper re-executes a Python process that lacks its guard; ros_env
    keeps the guard (and this process's library path), so a node's interpreter starts once."""
    def starts(env: dict[str, str]) -> int:
        done = subprocess.run([sys.executable, '-X', 'importtime', '-c', 'import rclpy'],
                              env=env, capture_output=True, text=True, timeout=60)
        assert done.returncode == 0, done.stderr[-2000:]
        return sum(line.rstrip().endswith('| encodings')    # once per interpreter start
                   for line in done.stderr.splitlines())

    assert starts(ros_env(42)) == 1
    assert starts(ros_env(42, base={k: v for k, v in os.environ.items()
                                    if k != 'LD_LIBRARY_PATH'})) == 2


def test_a_node_runs_one_blas_thread_unless_told_otherwise() -> None:
    assert ros_env(42, base={})['OPENBLAS_NUM_THREADS'] == '1'
    assert ros_env(42, base={'OPENBLAS_NUM_THREADS': '4'})['OPENBLAS_NUM_THREADS'] == '4'
    threads = subprocess.run(
        [sys.executable, '-c', 'from threadpoolctl import threadpool_info; import numpy; '
         'print(*[p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"])'],
        env=ros_env(42, base={'PATH': '/bin'}), capture_output=True, text=True, timeout=30)
    assert threads.stdout.split() == ['1'], threads.stderr


def test_graph_has_one_controller_and_the_control_nodes() -> None:
    names = [s.name for s in load_graph('sim')]
    assert names[0] == 'flexarm_sim'
    assert {'flexarm_vision', 'flexarm_learner', 'flexarm_compensator'} <= set(names)
    with pytest.raises(ValueError, match='unknown robot'):
        load_graph('nonexistent')


def test_the_tools_address_nodes_by_the_names_graph_yaml_gives_their_roles(tmp_path) -> None:
    specs = all_nodes()
    assert len({s.role for s in specs}) == len(specs)          # a role names one node
    assert node_name('learner') == 'flexarm_learner'
    assert controllers() == {'flexarm_sim': 'sim', 'flexarm_bridge': 'bridge'}
    with pytest.raises(ValueError, match="no node of role 'planner'.*'learner'"):
        node_name('planner')
    graph = yaml.safe_load(config_path('graph.yaml').read_text(encoding='utf-8'))
    learner = next(n for n in graph['nodes'] if n['role'] == 'learner')
    learner['name'] = 'arm_learner'
    graph['robots']['sim'][0]['name'] = 'arm_sim'
    renamed = tmp_path / 'graph.yaml'
    renamed.write_text(yaml.safe_dump(graph), encoding='utf-8')
    assert node_name('learner', renamed) == 'arm_learner'
    assert controllers(renamed)['arm_sim'] == 'sim'


def test_each_node_specific_params_section_names_a_node_of_the_graph() -> None:
    """A node renamed in graph.yaml but not in its params files would start on code
    defaults: every ``/**/<name>`` section of a node's files is the name of a node."""
    names = {s.name for s in all_nodes()}
    for spec in all_nodes():
        for file in spec.params_files:
            sections = yaml.safe_load(config_path(file).read_text(encoding='utf-8'))
            own = {key.removeprefix('/**/') for key in sections if key != '/**'}
            assert own <= names, (file, own - names)


def _supervisor(tmp_path, body: str) -> subprocess.Popen:
    """A Python process that starts a ``sleeper`` node (which ignores SIGINT) and runs ``body``.

    It prints the node's pid first, then whatever ``body`` prints once the node is ready.
    """
    (tmp_path / 'sleeper.py').write_text(
        'import signal, time\nsignal.signal(signal.SIGINT, signal.SIG_IGN)\nprint("ready")\n'
        'time.sleep(60)\n')
    script = textwrap.dedent(f'''
        import time
        from pathlib import Path
        from flexarm_bringup.launcher import NodeProcess, NodeSpec, ros_env, stop_all
        env = ros_env(0, base={{'PYTHONPATH': {str(tmp_path)!r}}})
        node = NodeProcess(NodeSpec(name='sleeper', module='sleeper'), env,
                           Path({str(tmp_path)!r}) / 'sleeper.log')
        node.start()
        print(node.process.pid, flush=True)
        for _ in range(200):
            if 'ready' in node.log_tail():
                break
            time.sleep(0.05)
    ''') + textwrap.dedent(body)
    return subprocess.Popen([sys.executable, '-c', script], stdout=subprocess.PIPE, text=True)


def _gone(pid: int, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


def test_nodes_die_with_a_supervisor_killed_by_sigkill(tmp_path) -> None:
    supervisor = _supervisor(tmp_path, 'time.sleep(60)\n')
    try:
        node_pid = int(supervisor.stdout.readline())
        supervisor.kill()
        supervisor.wait(timeout=10)
        assert _gone(node_pid, 10.0)
    finally:
        supervisor.kill()
        supervisor.stdout.close()


def test_a_second_interrupt_does_not_cut_the_shutdown_short(tmp_path) -> None:
    supervisor = _supervisor(tmp_path, '''
        print('stopping', flush=True)
        print(stop_all([node], timeout=3.0)['sleeper'], flush=True)
    ''')
    try:
        node_pid = int(supervisor.stdout.readline())
        assert supervisor.stdout.readline().strip() == 'stopping'
        time.sleep(1.0)                       # the node ignores SIGINT: stop_all waits
        supervisor.send_signal(signal.SIGINT)
        assert supervisor.stdout.readline().strip() == str(-signal.SIGTERM)
        assert supervisor.wait(timeout=10) == 0
        assert _gone(node_pid, 1.0)
    finally:
        supervisor.kill()
        supervisor.stdout.close()


def test_a_node_killed_by_another_process_leaves_no_shared_memory(tmp_path, wait_for) -> None:
    """Gone, a process can no longer be asked what it owned: its watch noted that while it
    ran, and closing the node removes it (the faults harness's SIGKILLs, a crash)."""
    token = secrets.token_hex(8)
    segment, port = SHM_DIR / f'fastrtps_{token}', SHM_DIR / f'fastrtps_port{100000 + os.getpid()}'
    files = [segment, SHM_DIR / f'{segment.name}_el', port, SHM_DIR / f'sem.{port.name}_mutex']
    (tmp_path / 'participant.py').write_text(  # a participant: its segment's lock, a port mapped
        'import fcntl, mmap, pathlib, time\n'
        f'segment, port = pathlib.Path({str(segment)!r}), pathlib.Path({str(port)!r})\n'
        'lock = open(f"{segment}_el", "wb"); fcntl.flock(lock, fcntl.LOCK_EX)\n'
        'segment.write_bytes(bytes(4096)); port.write_bytes(bytes(4096))\n'
        'port.with_name(f"sem.{port.name}_mutex").write_bytes(bytes(64))\n'
        'handles = [open(path, "r+b") for path in (segment, port)]\n'
        'mapped = [mmap.mmap(handle.fileno(), 4096) for handle in handles]\n'
        'print("ready", flush=True); time.sleep(60)\n')
    node = NodeProcess(NodeSpec(name='participant', module='participant'),
                       ros_env(0, base={'PYTHONPATH': str(tmp_path)}),
                       tmp_path / 'participant.log')
    try:
        node.start()
        wait_for(lambda: set(files) <= node.shm.owned, 20.0, 'its watch to note its files')
        os.kill(node.process.pid, signal.SIGKILL)
        node.process.wait(10)
        node.close()
        assert [path.name for path in files if path.exists()] == []
    finally:
        node.signal(signal.SIGKILL)
        node.close()
        for path in files:
            path.unlink(missing_ok=True)
