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


def test_cli_synth_named_thin_scene(tmp_path):
    import numpy as np
    from click.testing import CliRunner

    from plenodecode.cli.main import cli

    args = ["synth", "illum-mini", "-o", str(tmp_path), "--shape", "420", "560", "--no-noise", "--no-lightfield"]
    res = CliRunner().invoke(cli, [*args, "--scene", "slits-h-j2-weak"])
    assert res.exit_code == 0, res.output
    truth = syn.load_truth(tmp_path / "scene.truth.json")
    assert truth.scene.name == "slits-h-j2-weak" and truth.disparity_range == (-1.0, 1.0)
    far = truth.disparity == -1.0
    assert set(np.unique(truth.disparity)) == {-1.0, 1.0} and 0.15 < far.mean() < 0.45   # slits of 1..5 in 7..11 px
    left = far[:, : far.shape[1] // 2 - 1]                 # horizontal slits: rows of a panel are all far or all near
    assert (left.all(axis=1) | ~left.any(axis=1)).all() and left.all(axis=1).sum() >= 4
    for bad in (["--scene", "picket-fence"], ["--scene", "slats-v-j1-tex"]):
        argv = [*args, *bad] if bad[1] == "picket-fence" else ["synth", "raytrix", "-o", str(tmp_path / "r"), *bad]
        res = CliRunner().invoke(cli, argv)
        assert res.exit_code == 2 and "--scene" in res.output, res.output
    assert not (tmp_path / "r").exists()
