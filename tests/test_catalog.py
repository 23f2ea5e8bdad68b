"""Discovery: default_config, scenes, the sensor and PettingZoo lists and `khepera-gym list`
answer from the registries, and name what they do not know."""

from __future__ import annotations

import gymnasium as gym
import pytest

import khepera_gym
from khepera_gym import _core, cli, pettingzoo, registry
from khepera_gym.errors import ConfigError
from khepera_gym.learning.policies import POLICY_NAMES
from khepera_gym.registration import registered_ids


@pytest.mark.parametrize("task", registry.task_names())
def test_default_config_is_the_cores_for_every_version_the_task_exists_in(task: str) -> None:
    versions = registry.task_versions(task)
    assert versions and versions[-1] == _core.LATEST_VERSION
    for version in versions:
        assert khepera_gym.default_config(task, version) == _core.default_config(task, version)
    assert khepera_gym.default_config(task) == _core.default_config(task)


def test_default_config_names_the_tasks_and_points_a_scene_to_scenes() -> None:
    with pytest.raises(ConfigError, match=r"unknown task 'bogus'.*nav"):
        khepera_gym.default_config("bogus")
    with pytest.raises(ConfigError, match=r"scene: see khepera_gym.scenes\(\)"):
        khepera_gym.default_config("paper_fig6")
    with pytest.raises(ConfigError, match="exists from version 1"):
        khepera_gym.default_config("track", 0)


def test_task_versions_are_the_registered_ids_versions() -> None:
    for task, ids in registered_ids().items():
        assert [int(i.rsplit("-v", 1)[1]) for i in ids] == list(registry.task_versions(task))


def test_scenes_are_the_builtin_files_that_are_not_tasks_each_with_a_summary() -> None:
    scenes = khepera_gym.scenes()
    assert set(scenes) == set(_core.builtin_configs()) - set(registry.task_names())
    assert {"paper_fig6", "paper_fig7", "swarm"} <= set(scenes)
    for name, summary in scenes.items():
        assert summary.endswith(".") and len(summary) > 20, name
        assert registry.scene_config(name) == _core.default_config(name)
    with pytest.raises(ConfigError, match="unknown scene 'nav'"):
        registry.scene_config("nav")


def test_a_scene_loads_on_the_task_it_names() -> None:
    env = gym.make("KheperaIV-Avoid-v1", config="paper_fig6")
    env.reset(seed=0)
    assert len(env.unwrapped.scene()["obstacles"]) == 2
    env.close()


def test_sensors_are_the_cores_with_their_blocks_and_keys() -> None:
    sensors = {sensor.name: sensor for sensor in registry.sensors()}
    assert list(sensors)[:2] == ["ir", "us"]
    assert sensors["ir"].values == 8 and sensors["us"].values == 5
    assert sensors["ir"].observed and sensors["gyro"].carried and not sensors["gyro"].observed
    assert "ir_noise_sigma" in sensors["ir"].keys
    for sensor in sensors.values():  # every one can be carried and observed by itself
        env = gym.make("KheperaIV-Nav-v1", carry=[sensor.name], observe=[sensor.name])
        assert env.unwrapped.obs_layout()[sensor.name].stop == sensor.values
        env.close()


def test_pettingzoo_modules_are_every_versioned_module_of_the_package() -> None:
    import khepera_gym.pettingzoo as package

    modules = pettingzoo.module_infos()
    assert {m.name for m in modules} == {n for n in package.__all__ if "_v" in n}
    for module in modules:
        assert module.env_class.metadata["name"] == module.name
        assert module.version in registry.task_versions(module.task)
        env = module.module.parallel_env()
        assert env.unwrapped._batch.task == module.task
        env.close()


def test_list_prints_every_id_module_scene_sensor_and_policy(capsys) -> None:
    assert cli.main(["list"]) == 0
    text = capsys.readouterr().out
    for ids in registered_ids().values():
        for env_id in ids:
            assert env_id in text
    for module in pettingzoo.module_infos():
        assert module.name in text
    for name in (*khepera_gym.scenes(), *(s.name for s in registry.sensors()), *POLICY_NAMES):
        assert f"  {name} " in text, name


def test_list_prints_only_the_topics_asked_and_refuses_others(capsys) -> None:
    assert cli.main(["list", "scenes"]) == 0
    text = capsys.readouterr().out
    assert "paper_fig6" in text and "KheperaIV-Nav" not in text
    with pytest.raises(SystemExit, match="unknown topic 'bogus'"):
        cli.main(["list", "bogus"])
