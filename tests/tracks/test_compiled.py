"""A compiled kernel older than its source is not used: the caller gets None (its Python reference) and a line
on stderr; a kernel built after its sources, or one without sources beside it, is used."""

import os
import sys

import pytest

from tracks.compiled import compiled_module, kernel_sources


@pytest.fixture
def package(tmp_path, monkeypatch):
    pkg = tmp_path / "kpkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "k.pyx").write_text('cdef extern from "k_raster.h":\n    pass\n')
    (pkg / "k_raster.h").write_text("")
    (pkg / "k.py").write_text("VALUE = 1\n")  # stands for the built extension module
    monkeypatch.syspath_prepend(str(tmp_path))
    yield pkg
    for name in ("kpkg.k", "kpkg"):
        sys.modules.pop(name, None)


def _age(path, seconds):
    st = path.stat()
    os.utime(path, (st.st_atime, st.st_mtime - seconds))


def test_the_sources_are_the_pyx_and_its_headers(package):
    assert kernel_sources(package / "k.py") == [package / "k.pyx", package / "k_raster.h"]


def test_a_kernel_built_after_its_sources_is_used(package, capsys):
    _age(package / "k.pyx", 100)
    _age(package / "k_raster.h", 100)
    assert compiled_module("kpkg.k").VALUE == 1
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("source", ["k.pyx", "k_raster.h"])
def test_a_kernel_older_than_a_source_is_not_used(package, capsys, source):
    _age(package / "k.py", 100)
    for other in ("k.pyx", "k_raster.h"):
        _age(package / other, 200 if other != source else 0)
    assert compiled_module("kpkg.k") is None
    assert f"older than {source}" in capsys.readouterr().err


def test_switched_off_by_the_environment(package, monkeypatch):
    monkeypatch.setenv("LD3_COMPILED", "0")
    assert compiled_module("kpkg.k") is None

