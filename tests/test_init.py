"""Importing the package stays light: the heavy libraries load when a command or function needs them."""

import json
import subprocess
import sys

from tests.conftest import ROOT

HEAVY = ("matplotlib", "colour", "dask", "distributed", "zarr", "numba", "cv2")


def _imported_after(code: str) -> list[str]:
    probe = code + f"\nimport json, sys\nprint(json.dumps(sorted({{m.split('.')[0] for m in sys.modules}} & {set(HEAVY)!r})))\n"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True,
                         cwd=str(ROOT)).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_import_plenodecode_imports_no_heavy_library():
    assert _imported_after("import plenodecode") == []


def test_cli_and_pipeline_import_no_heavy_library():
    assert _imported_after("import plenodecode.cli.main, plenodecode.pipeline, plenodecode.io.images") == []


def test_version_and_help_import_no_heavy_library():
    code = ("from click.testing import CliRunner\nfrom plenodecode.cli.main import cli\n"
            "for args in (['--version'], ['--help']):\n    assert CliRunner().invoke(cli, args).exit_code == 0\n")
    assert _imported_after(code) == []
