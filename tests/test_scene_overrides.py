"""A misspelt scene key names the key it probably is, and ``--set KEY=VALUE`` changes a scene from
the command line, validated exactly as the file (issue 35)."""
import copy

import pytest
import yaml
from conftest import ROOT, run_cli_here

from app.scene.schema import SceneError, parse_scene, with_overrides

DEFAULT = ROOT / "app" / "scenes" / "villechaise_block.yaml"


def _error(mutate) -> str:
    data = yaml.safe_load(DEFAULT.read_text())
    mutate(data)
    with pytest.raises(SceneError) as err:
        parse_scene(data)
    return str(err.value)


@pytest.mark.parametrize("mutate,where,meant", [
    (lambda d: d["system"].update(nxx=d["system"].pop("nx")), "system.nxx", "nx"),
    (lambda d: d.update(analyse=d.pop("analyses")), "analyse", "analyses"),
    (lambda d: d.update(mU=d.pop("mu")), "mU", "mu"),
    (lambda d: d["loading"].update(normal_forse=d["loading"].pop("normal_force")), "loading.normal_forse",
     "normal_force"),
    (lambda d: d.update(settings={"mcp": {"certify_onset_node": 5}}), "settings.mcp.certify_onset_node",
     "certify_onset_nodes"),
    (lambda d: d.update(outputs={"plot": True}), "outputs.plot", "plots"),
    (lambda d: d.update(sytem=d.pop("system")), "sytem", "system"),     # also 'system' missing: the typo is named
])
def test_a_misspelt_key_names_the_key_it_probably_is(mutate, where, meant):
    assert _error(mutate) == f"scene: unknown key '{where}' (not allowed here; did you mean '{meant}'?)"


def test_an_unknown_key_far_from_every_allowed_one():
    assert _error(lambda d: d["system"].update(foo=1)) == \
        "scene: unknown key 'system.foo' (not allowed here; check the spelling)"


def test_overrides_set_keys_as_the_file_would():
    data = yaml.safe_load(DEFAULT.read_text())
    out = with_overrides(copy.deepcopy(data), ["mu=0.8", "system.nx=40", "analyses=[mceip_mu]",
                                               "settings.mcp.certify_onset_nodes=5000", "outputs={plots: false}"])
    scene = parse_scene(out)
    assert scene.mu == 0.8 and scene.system.nx == 40 and list(scene.analyses) == ["mceip_mu"]
    assert scene.settings.mcp.certify_onset_nodes == 5000 and scene.outputs.plots is False
    assert scene.system.ny == data["system"]["ny"]                        # the rest as in the file


@pytest.mark.parametrize("item,message", [
    ("mu", "--set 'mu': expected KEY=VALUE"),
    ("=3", "--set '=3': expected KEY=VALUE"),
    ("system..nx=3", "--set 'system..nx=3': expected KEY=VALUE"),
    ("mu=[1", "--set 'mu=[1': the value is not valid YAML"),
    ("mu.x=1", "--set 'mu.x=1': 'mu' is not a mapping or a list"),
    ("analyses.7=mceip_mu", "--set 'analyses.7=mceip_mu': 'analyses.7': the list has 4 entries (0 to 3)"),
])
def test_a_malformed_override_is_one_line(item, message):
    with pytest.raises(SceneError, match=None) as err:
        with_overrides(yaml.safe_load(DEFAULT.read_text()), [item])
    assert str(err.value).startswith(message) and "\n" not in str(err.value)


def test_the_command_line_validates_overrides_like_the_file():
    ok = run_cli_here("validate", str(DEFAULT), "--set", "mu=0.8", "--set", "system.nx=40", "--set", "system.ny=20")
    assert ok.returncode == 0 and "mu = 0.8" in ok.stdout and "41 contact nodes" in ok.stdout
    bad = run_cli_here("validate", str(DEFAULT), "--set", "mu=-1")
    assert bad.returncode == 2
    assert bad.stderr.startswith(f"error: {DEFAULT} with --set: mu = -1: ") and len(bad.stderr.splitlines()) == 1
    typo = run_cli_here("validate", str(DEFAULT), "--set", "sistem.nx=4")
    assert typo.returncode == 2 and "unknown key 'sistem' (not allowed here; did you mean 'system'?)" in typo.stderr
