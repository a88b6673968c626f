"""The synth command: a synthetic raw, its white image and the ground truth."""

from __future__ import annotations

from plenodecode import synthetic as syn


def test_cli_synth_writes_files_and_refuses_to_overwrite(tmp_path):
    from click.testing import CliRunner

    from plenodecode.cli.main import cli
    from plenodecode.cli.synth import PRESET_CHOICE

    assert set(PRESET_CHOICE.choices) == set(syn.PRESETS)
    args = ["synth", "f01-mini", "-o", str(tmp_path), "--seed", "3", "--offset", "0.25", "-0.4",
            "--shape", "96", "128", "--no-noise"]
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 0, res.output
    assert "scene.lfp" in res.output and "MOD_0000.RAW" in res.output
    truth = syn.load_truth(tmp_path / "scene.truth.json")
    assert truth.grid.to_dict() == syn.make_grid("f01-mini", offset=(0.25, -0.4), shape=(96, 128)).to_dict()
    assert truth.document["noise"] is False and truth.seed == 3
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 2 and "--overwrite" in res.output
    res = CliRunner().invoke(cli, [*args, "--overwrite"])
    assert res.exit_code == 0, res.output
