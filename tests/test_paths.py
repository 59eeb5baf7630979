"""Output locations are checked before a command works: one reason, naming the option."""

from __future__ import annotations

from pathlib import Path

import pytest

from tire_estimation.errors import ConfigError
from tire_estimation.paths import check_new_path, prepare_out_dir


def test_prepare_out_dir_creates_and_checks(tmp_path: Path) -> None:
    out = prepare_out_dir(tmp_path / "a" / "b")
    assert out.is_dir() and list(out.iterdir()) == []  # the write check leaves nothing
    afile = tmp_path / "f"
    afile.write_text("x")
    for path, reason in (
        (afile, "is a file, not a directory"),
        (afile / "sub", "cannot create the directory: Not a directory"),
        (tmp_path / ("n" * 300), "cannot create the directory: File name too long"),
        (Path("/sys/kernel"), "cannot write in it"),
    ):
        with pytest.raises(ConfigError) as exc:
            prepare_out_dir(path, "--out")
        assert exc.value.field == "--out" and exc.value.reason.startswith(reason), exc.value


def test_check_new_path(tmp_path: Path) -> None:
    check_new_path(tmp_path / "new" / "bag")
    (tmp_path / "bag").mkdir()
    with pytest.raises(ConfigError, match="exists; pass --overwrite"):
        check_new_path(tmp_path / "bag")
    check_new_path(tmp_path / "bag", overwrite=True)
    with pytest.raises(ConfigError, match="File name too long"):
        check_new_path(tmp_path / ("n" * 300))
    (tmp_path / "f").write_text("x")
    with pytest.raises(ConfigError, match="its directory is a file"):
        check_new_path(tmp_path / "f" / "bag", "--write-config")
