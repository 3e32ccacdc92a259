"""``flexarm keygen``: a new site key for the controller link, never one written over."""
from flexarm_bridge.link_auth import load_key
from flexarm_cli import main


def test_keygen_writes_a_key_and_never_overwrites_one(tmp_path, capsys):
    path = tmp_path / 'site.key'
    assert main(['keygen', str(path)]) == 0
    key = load_key(path)
    assert main(['keygen', str(path)]) == 1                # would lock out its users
    assert 'exists' in capsys.readouterr().err and load_key(path) == key
