"""Every ```python block of docs/python.md runs as written (the docs cannot drift from the
package): each block is executed in a fresh namespace, in a temporary directory that sees the
repository's fixtures, so what a block writes stays there."""

import os
import re

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
DOC = os.path.join(ROOT, "docs", "python.md")


def blocks():
    text = open(DOC, encoding="utf-8").read()
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_the_page_has_python_blocks():
    assert len(blocks()) >= 3


@pytest.mark.parametrize("k", range(len(blocks())))
def test_block_runs_as_written(k, tmp_path, monkeypatch):
    code = blocks()[k]
    if "femp.mesh" in code:
        pytest.importorskip("gmsh")
        pytest.importorskip("meshio")
    os.symlink(os.path.join(ROOT, "fixtures"), tmp_path / "fixtures")
    monkeypatch.chdir(tmp_path)
    exec(compile(code, f"docs/python.md, block {k + 1}", "exec"), {"__name__": "__docs__"})
    # And again: a second run of the same block (outputs already there) must work too.
    exec(compile(code, f"docs/python.md, block {k + 1}", "exec"), {"__name__": "__docs__"})


def test_the_installed_package_ships_its_types():
    import femp

    here = os.path.dirname(femp.__file__)
    for f in ("py.typed", "_femp.pyi", "__init__.py"):
        assert os.path.isfile(os.path.join(here, f)), f
    if os.environ.get("FEMP_TEST_INSTALLED"):
        # crates/python/test.sh: the tests run against the installed wheel.
        assert "site-packages" in here, here
