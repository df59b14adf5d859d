"""rose_logs.datasets: where the real data set is found, and the messages when it is not."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rose_logs import datasets
from rose_logs.datasets import ENV_VAR, DataSetError, data_dir, data_path, require_data_dir


def test_environment_variable_wins(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "maps" / "sub").mkdir(parents=True)
    monkeypatch.setenv(ENV_VAR, str(tmp_path / "maps"))
    assert data_dir() == tmp_path / "maps"
    assert require_data_dir() == tmp_path / "maps"
    assert data_path("sub") == tmp_path / "maps" / "sub"


def test_missing_folder_named_by_the_variable_is_an_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(ENV_VAR, str(tmp_path / "typo"))
    assert data_dir() == tmp_path / "typo"  # reported, not silently replaced by a default
    expected = re.escape(f"{tmp_path / 'typo'}: data-set folder ({ENV_VAR}) does not exist")
    with pytest.raises(DataSetError, match=expected):
        require_data_dir()
    (tmp_path / "typo").write_text("")  # a file: said so, not "does not exist"
    with pytest.raises(DataSetError, match="is a file, not a folder"):
        require_data_dir()


def test_missing_file_inside_the_data_set(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(ENV_VAR, str(tmp_path))
    with pytest.raises(DataSetError, match=r"nothing\.png: not in the data set") as info:
        data_path("nothing.png")
    assert "\n" not in str(info.value)
    assert ENV_VAR in str(info.value)


def test_default_is_shared_maps_beside_the_checkout(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv(ENV_VAR, raising=False)
    # A fake checkout: <tmp>/repo/pyproject.toml and <tmp>/repo/rose_logs/datasets.py.
    repo = tmp_path / "repo"
    (repo / "rose_logs").mkdir(parents=True)
    (repo / "pyproject.toml").write_text("")
    monkeypatch.setattr(datasets, "__file__", str(repo / "rose_logs" / "datasets.py"))
    assert data_dir() is None
    with pytest.raises(DataSetError, match=f"set {ENV_VAR}"):
        require_data_dir()
    (tmp_path / "shared" / "maps").mkdir(parents=True)
    assert data_dir() == tmp_path / "shared" / "maps"
    # Not a source checkout (an installed package): no default.
    (repo / "pyproject.toml").unlink()
    assert data_dir() is None


def test_empty_variable_means_unset(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(ENV_VAR, "  ")
    assert data_dir() == datasets.checkout_data_dir()


def test_no_machine_paths_in_the_repository() -> None:
    # The repository must not depend on where one machine keeps the data.
    root = Path(__file__).resolve().parents[1]
    offenders = []
    for folder in ("rose", "rose_logs", "tests", "benchmarks", "sample_data"):
        for path in sorted((root / folder).rglob("*")):
            if path.suffix not in (".py", ".md", ".toml", ".yaml", ".txt") or path == Path(
                __file__
            ):
                continue
            text = path.read_text(errors="replace")
            if "/work/" in text or "/home/" in text or "/root/" in text:
                offenders.append(str(path.relative_to(root)))
    assert offenders == []


def test_an_evaluation_without_the_data_set_points_to_maps_dir(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A fresh clone has tests/data: the error named only ROSE_DATA_DIR and ../shared/maps."""
    from rose_logs.evaluation.config import EvaluationConfig

    monkeypatch.setenv(ENV_VAR, str(tmp_path / "absent"))
    with pytest.raises(DataSetError, match=r"or give --maps-dir \(the small configuration"):
        EvaluationConfig.small().data_root  # noqa: B018 (the property raises)
