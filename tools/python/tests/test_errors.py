"""Failures of the Rust side arrive as echofield.Error with the message the
command line prints (file, record, field); argument mistakes as
ValueError / TypeError."""

import pytest

import echofield


def test_missing_mission_names_the_path(tmp_path):
    missing = tmp_path / "nowhere.mcap"
    with pytest.raises(echofield.Error, match="nowhere"):
        echofield.load_mission(missing)
    with pytest.raises(echofield.Error, match="nowhere"):
        echofield.run(missing)


def test_corrupt_mcap_names_the_file(tmp_path, tank_path):
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(tank_path.read_bytes()[:5000])
    with pytest.raises(echofield.Error, match="cut.mcap"):
        echofield.load_mission(cut)


def test_unknown_config_key_is_named(tank):
    with pytest.raises(echofield.Error, match=r"loops\.no_such_key"):
        echofield.run(tank, config={"loops": {"no_such_key": 1}})


def test_invalid_config_value_is_named(tank):
    with pytest.raises(echofield.Error, match=r"loops\.max_candidates_per_node"):
        echofield.run(tank, config={"loops": {"max_candidates_per_node": "four"}})


def test_config_file_errors_name_the_file(tmp_path, tank):
    bad = tmp_path / "bad.toml"
    bad.write_text("[loops]\nno_such_key = 1\n")
    with pytest.raises(echofield.Error, match=r"bad\.toml.*loops\.no_such_key"):
        echofield.run(tank, config=bad)


def test_wrong_argument_types():
    with pytest.raises(TypeError, match="mission"):
        echofield.run(42)
    with pytest.raises(TypeError, match="config"):
        echofield.run("x.mcap", config=3.5)
    with pytest.raises(ValueError, match="topics"):
        echofield.load_mission("x.mcap", topics={"camera": "/cam"})


def test_unknown_scenario_and_simulator_key():
    with pytest.raises(echofield.Error, match="lake"):
        echofield.simulate("lake")
    with pytest.raises(echofield.Error, match="binz"):
        echofield.simulate("tank", config={"sonar": {"binz": 120}})


def test_output_folder_in_the_way_is_refused_before_any_work(tmp_path, tank):
    out = tmp_path / "out"
    out.mkdir()
    (out / "thesis.tex").write_text("keep me")
    with pytest.raises(echofield.Error, match="thesis.tex"):
        echofield.run(tank, output=out)
    assert (out / "thesis.tex").read_text() == "keep me"
