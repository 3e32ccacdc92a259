"""The URDF's ``<ros2_control>`` block for a real driver: its plugin and its parameters."""
import pytest

from flexarm_core.kinematics import ArmGeometry
from flexarm_core.params import load_config
from flexarm_description.urdf_model import hardware_parameters, ros2_control


def test_a_real_driver_gets_its_hardware_parameters():
    geometry = ArmGeometry.from_dict(load_config('arm.yaml')['arm'])
    params = hardware_parameters(['robot_ip = 192.0.2.10', 'port=50001', ''])
    assert params == {'robot_ip': '192.0.2.10', 'port': '50001'}
    hardware = ros2_control(geometry, 'vendor/ArmSystem', params).find('hardware')
    assert hardware.findtext('plugin') == 'vendor/ArmSystem'
    assert {p.get('name'): p.text for p in hardware.iter('param')} == params
    with pytest.raises(ValueError, match="'robot_ip'"):
        hardware_parameters(['robot_ip'])
