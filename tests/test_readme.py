"""The README's Python tour runs as written (issue 7: examples are tests)."""

import os
import re
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]


def _python_blocks() -> list[str]:
    text = (ROOT / "README.md").read_text()
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_readme_has_a_python_tour():
    assert len(_python_blocks()) >= 1


def test_readme_python_tour_runs(tmp_path, monkeypatch):
    """All python blocks run in order in one namespace, from a scratch copy of the working directory."""
    monkeypatch.chdir(ROOT)
    monkeypatch.setenv("PLENODECODE_TOUR_OUT", str(tmp_path))
    namespace: dict = {"__name__": "__readme__"}
    for i, block in enumerate(_python_blocks()):
        code = compile(block.replace("tour_out/", f"{tmp_path}{os.sep}"), f"README.md[python block {i}]", "exec")
        exec(code, namespace)  # noqa: S102 - the README's own examples
