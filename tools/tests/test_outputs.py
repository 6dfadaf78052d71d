"""dynid.outputs: a command's outputs put in place together when it succeeds, none when it fails, and the files they
would have replaced as they were (the commands' end-to-end cases: test_cli.py, test_interrupt.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

from dynid.errors import DataError
from dynid.outputs import atomic_write, output_dir, staged


def text(data: bytes):  # noqa: ANN201 - atomic_write's writer
    return lambda f: f.write(data)


def test_outputs_appear_together_at_the_end(tmp_path: Path) -> None:
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    with staged():
        atomic_write(a, text(b"A"))
        assert not a.exists()  # staged: not yet in place
        with staged():  # a nested block joins the command's staging
            atomic_write(b, text(b"B"))
        assert not b.exists()
    assert a.read_bytes() == b"A" and b.read_bytes() == b"B"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.json"]  # no temporary file left


def test_a_failing_command_leaves_nothing_and_the_old_files(tmp_path: Path) -> None:
    old = tmp_path / "model.json"
    old.write_bytes(b"OLD")
    with pytest.raises(RuntimeError), staged():
        atomic_write(old, text(b"NEW"))
        output_dir(tmp_path / "figures" / "deep")
        atomic_write(tmp_path / "figures" / "deep" / "f.png", text(b"PNG"))
        raise RuntimeError("the command fails after writing")
    assert old.read_bytes() == b"OLD" and [p.name for p in tmp_path.iterdir()] == ["model.json"]


def test_a_rename_that_fails_at_the_end_restores_what_was_replaced_and_names_its_output(tmp_path: Path) -> None:
    """A review found the rollback unlinking the first output after it had replaced the user's file (the old model
    lost) and naming the wrong output."""
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_bytes(b"OLD MODEL")
    with pytest.raises(DataError, match=r"cannot write '.*b\.json': Is a directory"), staged():
        atomic_write(a, text(b"NEW A"))
        atomic_write(b, text(b"NEW B"))
        b.mkdir()  # b.json becomes a directory before the end: its rename fails after a.json's succeeded
    assert a.read_bytes() == b"OLD MODEL"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.json"] and b.is_dir()


def test_a_file_system_without_hard_links_still_takes_the_outputs(tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """The backup of a replaced file is a hard link; where the file system has none (vfat, some network mounts) the
    command's outputs still replace the old files, without a backup, instead of failing after all its work."""
    import os

    old = tmp_path / "model.json"
    old.write_bytes(b"OLD")

    def no_links(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "link", no_links)
    with staged():
        atomic_write(old, text(b"NEW"))
    assert old.read_bytes() == b"NEW" and [p.name for p in tmp_path.iterdir()] == ["model.json"]


def test_unstaged_writes_are_in_place_at_once(tmp_path: Path) -> None:
    atomic_write(tmp_path / "x", text(b"X"))
    assert (tmp_path / "x").read_bytes() == b"X" and [p.name for p in tmp_path.iterdir()] == ["x"]


def test_an_output_on_a_file_the_command_read_through_its_configuration_is_refused(tmp_path: Path) -> None:
    """The robot configuration and its URDF are read without an option naming them (a model file's robot, a
    configuration's `urdf`): an output on either is refused at its write, and the command leaves nothing (a TIAGo
    walkthrough's `export --model M --urdf` onto the configuration's own URDF replaced it, exit 0, and the model
    could no longer be read: its URDF digest no longer matched)."""
    from dynid.config.robot_config import load_config

    config = tmp_path / "cfg.yaml"
    config.write_text(Path(load_config("icub_right_arm").source).read_text())
    urdf = tmp_path / "arm.urdf"  # a copy: should the refusal regress, the bundled one stays as it is
    urdf.write_bytes(Path(load_config("icub_right_arm").urdf).read_bytes())
    before = urdf.read_bytes()
    for target, what in ((config, "the robot configuration"), (urdf, "icub_right_arm's URDF")):
        with pytest.raises(DataError, match=f"it is {what}, which the command reads"), staged():
            load_config(config, urdf)
            atomic_write(tmp_path / "other.json", text(b"A"))
            atomic_write(target, text(b"B"))
        assert not (tmp_path / "other.json").exists()
    assert urdf.read_bytes() == before and config.read_text().startswith("#")
    with staged():  # outside a command that read it, the file is an output like any
        atomic_write(config, text(b"C"))
    assert config.read_bytes() == b"C"
