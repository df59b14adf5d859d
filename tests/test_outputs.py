"""rose.outputs: output checks, staging, commit all-or-none, streams, stale temporaries, strict JSON."""

from __future__ import annotations

import errno
import json
import math
import os
import shutil
import signal
import stat
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from rose.errors import OutputError
from rose.outputs import (
    OutputSet,
    counted,
    json_text,
    process_tag,
    refuse_output_in_bag_folder,
    remove_stale_temporaries,
    temporary_name,
)
from rose.signals import Terminated, install_signal_handlers, interrupt_behind, signals_deferred


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if ".rose-" in p.name)


def test_json_is_strict_with_non_finite_as_null() -> None:
    payload = {"a": math.inf, "b": [-math.inf, math.nan, 1.5], "c": np.float32(np.nan), "d": (1, 2)}
    text = json_text(payload)
    assert json.loads(text, parse_constant=lambda c: pytest.fail(c)) == {
        "a": None,
        "b": [None, None, 1.5],
        "c": None,
        "d": [1, 2],
    }


def test_outputs_are_committed_together(tmp_path: Path) -> None:
    with OutputSet() as outputs:
        outputs.write_bytes(tmp_path / "a.json", b"a")
        outputs.write_bytes(tmp_path / "b.json", b"b")
        assert not (tmp_path / "a.json").exists()
    assert (tmp_path / "a.json").read_bytes() == b"a"
    assert (tmp_path / "b.json").read_bytes() == b"b"
    assert _leftovers(tmp_path) == []


def test_a_failure_commits_nothing(tmp_path: Path) -> None:
    (tmp_path / "b.json").write_bytes(b"old")
    with pytest.raises(RuntimeError), OutputSet(force=True) as outputs:
        outputs.write_bytes(tmp_path / "a.json", b"a")
        outputs.write_bytes(tmp_path / "b.json", b"b")
        raise RuntimeError
    assert not (tmp_path / "a.json").exists()
    assert (tmp_path / "b.json").read_bytes() == b"old"
    assert _leftovers(tmp_path) == []


def test_a_failing_rename_restores_what_was_replaced(tmp_path: Path) -> None:
    (tmp_path / "a.json").write_bytes(b"old a")
    outputs = OutputSet(force=True)
    outputs.write_bytes(tmp_path / "a.json", b"new a")
    staged_b = outputs.write_bytes(tmp_path / "b.json", b"new b")
    staged_b.temp.unlink()  # the second output vanished: commit must undo the first
    with pytest.raises(OutputError, match="not written"):
        outputs.commit()
    assert (tmp_path / "a.json").read_bytes() == b"old a"
    assert not (tmp_path / "b.json").exists()
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("relation", ["same", "inside", "contains", "symlink", "hardlink"])
def test_an_output_never_touches_an_input(tmp_path: Path, relation: str) -> None:
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("x")
    source = tmp_path / "in.mcap"
    source.write_bytes(b"input")
    target = {
        "same": source,
        "inside": bag / "out.mcap",
        "contains": tmp_path,
        "symlink": tmp_path / "link.mcap",
        "hardlink": tmp_path / "hard.mcap",
    }[relation]
    if relation == "symlink":
        target.symlink_to(source)
    if relation == "hardlink":
        os.link(source, target)
    words = {"inside": "inside the input", "contains": "a folder that holds the input"}
    with pytest.raises(
        OutputError, match=f"refusing to write {words.get(relation, 'over the input')}"
    ):
        OutputSet(inputs=[source, bag], force=True).stage(target, directory=relation == "contains")
    assert source.read_bytes() == b"input"


def test_one_path_for_two_outputs_is_refused(tmp_path: Path) -> None:
    outputs = OutputSet()
    (tmp_path / "sub").mkdir()
    with pytest.raises(OutputError, match=r"used for two outputs \(also as .*/sub/\.\./x\)"):
        outputs.check(tmp_path / "sub" / ".." / "x", tmp_path / "x")
    outputs.stage(tmp_path / "x")
    # The same name twice (--rrd x --json x) said "x: used for two outputs (also x)".
    with pytest.raises(OutputError, match=r"x: given for two outputs \(each needs a file"):
        outputs.stage(tmp_path / "x")
    outputs.abort()


def test_existing_output_needs_force(tmp_path: Path) -> None:
    (tmp_path / "r.json").write_text("keep")
    with pytest.raises(OutputError, match=r"exists already \(force=True replaces it\)"):
        OutputSet().check(tmp_path / "r.json")
    # A command's outputs name the command line's option.
    with pytest.raises(OutputError, match=r"exists already \(--force replaces it\)"):
        OutputSet(ends_run=True).check(tmp_path / "r.json")
    with OutputSet(force=True) as outputs:
        outputs.write_bytes(tmp_path / "r.json", b"new")
    assert (tmp_path / "r.json").read_bytes() == b"new"


def test_force_replaces_a_bag_folder_only_when_it_holds_nothing_else(tmp_path: Path) -> None:
    """Another log written into a bag folder, or notes beside it, went with the bag on --force."""
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("relative_file_paths:\n- bag_0.db3\n")
    for name in ("bag_0.db3", "bag_0.db3-wal"):
        (bag / name).write_bytes(b"x")
    for extra in ("notes.txt", "inner.mcap"):
        (bag / extra).write_text("mine")
        with pytest.raises(OutputError, match=f"holds other files too \\({extra}\\)"):
            OutputSet(force=True).stage(bag, directory=True)
        (bag / extra).unlink()
    outputs = OutputSet(force=True)
    outputs.stage(bag, directory=True)  # the bag's own files only: may be replaced
    outputs.abort()


def test_force_checks_a_bag_folder_again_when_it_replaces_it(tmp_path: Path) -> None:
    """A bag folder may be replaced when the run starts; a file put in it while the run wrote (notes,
    another log) went with it at commit, though the same file there at the start was refused."""
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("relative_file_paths:\n- bag_0.db3\n")
    (bag / "bag_0.db3").write_bytes(b"x")
    outputs = OutputSet(force=True)
    staged = outputs.stage(bag, directory=True)
    staged.temp.mkdir()
    (staged.temp / "metadata.yaml").write_text("new")
    (bag / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match=r"holds other files too \(notes.txt\)"):
        outputs.commit()
    outputs.abort()
    assert sorted(p.name for p in bag.iterdir()) == ["bag_0.db3", "metadata.yaml", "notes.txt"]
    assert (bag / "metadata.yaml").read_text().startswith("relative_file_paths")
    assert _leftovers(tmp_path) == []


def test_force_replaces_only_bag_folders(tmp_path: Path) -> None:
    photos = tmp_path / "photos"
    photos.mkdir()
    (photos / "a.jpg").write_bytes(b"jpg")
    with pytest.raises(OutputError, match="not a ROS 2 bag"):
        OutputSet(force=True).stage(photos, directory=True)
    with pytest.raises(OutputError, match="is a directory"):
        OutputSet(force=True).stage(photos)
    assert (photos / "a.jpg").read_bytes() == b"jpg"
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information:\n  version: 5\n")
    with OutputSet(force=True) as outputs:
        staged = outputs.stage(bag, directory=True)
        staged.temp.mkdir()
        (staged.temp / "metadata.yaml").write_text("new")
    assert (bag / "metadata.yaml").read_text() == "new"
    assert _leftovers(tmp_path) == []


def test_symlink_to_a_file_is_followed_and_kept(tmp_path: Path) -> None:
    real = tmp_path / "real.json"
    real.write_text("old")
    link = tmp_path / "link.json"
    link.symlink_to(real)
    with OutputSet(force=True) as outputs:
        outputs.write_bytes(link, b"new")
    assert link.is_symlink()
    assert real.read_text() == "new"


def test_devices_are_streamed_not_replaced(tmp_path: Path) -> None:
    with OutputSet(force=False) as outputs:
        staged = outputs.write_bytes(Path("/dev/null"), b"x")
        assert staged.stream
    assert Path("/dev/null").is_char_device()


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
def test_a_stream_that_cannot_be_written_leaves_no_file(tmp_path: Path) -> None:
    """`rose clean m.yaml -o out.yaml --json /dev/full` said error and exit 1, with out.yaml and
    out.pgm placed: streams were written after the files. Written first, a failure places none."""
    (tmp_path / "kept.pgm").write_bytes(b"old")
    with (
        pytest.raises(OutputError, match="/dev/full: cannot write"),
        OutputSet(force=True) as outputs,
    ):
        outputs.write_bytes(tmp_path / "out.yaml", b"yaml")
        outputs.write_bytes(tmp_path / "kept.pgm", b"new")
        outputs.write_bytes(Path("/dev/full"), b"{}")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.pgm"]
    assert (tmp_path / "kept.pgm").read_bytes() == b"old"


def test_dash_and_dev_stdout_stream_to_stdout(tmp_path: Path) -> None:
    code = (
        "import sys; from pathlib import Path; from rose.outputs import OutputSet\n"
        "with OutputSet() as o:\n"
        "    o.write_bytes(Path(sys.argv[1]), b'{}')\n"
    )
    for target in ("-", "/dev/stdout"):
        done = subprocess.run(
            [sys.executable, "-c", code, target],
            capture_output=True,
            check=True,
            env=dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1])),
        )
        assert done.stdout == b"{}"
    assert Path("/dev/stdout").is_symlink()


def test_dash_goes_to_a_text_stream_put_in_place_of_stdout(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A CLI called from Python with sys.stdout an io.StringIO (contextlib.redirect_stdout): '-'
    was an AttributeError traceback at commit, after all the work (a StringIO has no binary
    buffer). Text goes there as text; bytes that are no UTF-8 text are one error, nothing lost."""
    import io

    from rose.errors import StdoutError

    text = io.StringIO()
    monkeypatch.setattr(sys, "stdout", text)
    with OutputSet() as outputs:
        outputs.write_bytes("-", '{"W": "é"}'.encode())
    assert text.getvalue() == '{"W": "é"}'
    binary = r"^standard output: cannot write \(it takes text"
    with pytest.raises(StdoutError, match=binary), OutputSet() as outputs:
        outputs.write_bytes("-", b"P5\n\xff")
        outputs.write_bytes(tmp_path / "kept.yaml", b"yaml")
    assert not (tmp_path / "kept.yaml").exists()


def _touch_back(path: Path, seconds: float) -> None:
    """Make ``path`` and what it holds look unchanged for ``seconds``."""
    when = time.time() - seconds
    for item in (path, *path.rglob("*")):
        os.utime(item, (when, when))


def test_stale_temporaries_of_dead_processes_are_removed(tmp_path: Path) -> None:
    gone = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    )
    dead_pid, tag = int(gone.stdout), process_tag()
    made = {}
    for name, idle_s, removed in (
        (f".o.mcap.rose-tmp-{tag}-{dead_pid}-0badc0de", 0, True),  # ours, its process gone
        (temporary_name("o.rrd"), 2 * 86400, False),  # ours: this process is alive
        # Another host or PID namespace (a container): its pid means nothing here.
        (f".o.json.rose-tmp-otherhost_pidns1-{dead_pid}-0badc0de", 3600, False),
        (f".p.json.rose-old-otherhost_pidns1-{dead_pid}-0badc0de", 2 * 86400, True),
        (f".o.db3.rose-tmp-{dead_pid}-0badc0de", 3600, False),  # an older version's name
        (f".p.db3.rose-tmp-{dead_pid}-0badc0de", 2 * 86400, True),
        (".o.mcap.tmp", 2 * 86400, False),  # not ours
    ):
        path = tmp_path / name
        path.mkdir()
        (path / "o.mcap").write_bytes(b"half")
        _touch_back(path, idle_s)
        made[path] = removed
    assert sorted(remove_stale_temporaries(tmp_path)) == sorted(p for p, r in made.items() if r)
    assert all(path.exists() != removed for path, removed in made.items())


def test_a_temporary_in_use_by_another_container_is_not_removed(tmp_path: Path) -> None:
    # A run in another PID namespace of this host: its pid is absent here, but it is at work.
    other = tmp_path / f".o.mcap.rose-tmp-{process_tag()}x-999999999-0badc0de"
    other.mkdir()
    (other / "o.mcap").write_bytes(b"being written")
    assert remove_stale_temporaries(tmp_path) == []
    assert (other / "o.mcap").read_bytes() == b"being written"


def test_temporary_names_are_unique() -> None:
    names = {temporary_name("o.rrd") for _ in range(100)}
    assert len(names) == 100
    assert all(n.startswith(f".o.rrd.rose-tmp-{process_tag()}-{os.getpid()}-") for n in names)


def test_without_force_of_two_commits_one_wins(tmp_path: Path) -> None:
    first, second = OutputSet(), OutputSet()
    first.write_bytes(tmp_path / "o.json", b"first")
    second.write_bytes(tmp_path / "o.json", b"second")
    first.commit()
    with pytest.raises(OutputError, match="appeared while writing"):
        second.commit()
    assert (tmp_path / "o.json").read_bytes() == b"first"
    assert _leftovers(tmp_path) == []


def test_sigterm_removes_temporaries(tmp_path: Path) -> None:
    code = (
        "import sys, time; from pathlib import Path\n"
        "from rose.outputs import OutputSet\nfrom rose.signals import install_signal_handlers\n"
        "install_signal_handlers()\n"
        "try:\n"
        "    with OutputSet() as o:\n"
        "        o.write_bytes(Path(sys.argv[1]), b'x')\n"
        "        print('staged', flush=True)\n"
        "        time.sleep(30)\n"
        "except KeyboardInterrupt as err:\n"
        "    sys.exit(err.exit_code)\n"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code, str(tmp_path / "o.json")],
        stdout=subprocess.PIPE,
        env=dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1])),
    )
    assert proc.stdout is not None
    assert proc.stdout.readline() == b"staged\n"
    assert _leftovers(tmp_path)
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=30) == 128 + signal.SIGTERM
    assert list(tmp_path.iterdir()) == []


def test_an_interrupt_just_after_the_staging_folder_appears_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A signal handler runs between two bytecodes: the first chance is right after os.mkdir returns.
    real_mkdir = os.mkdir

    def mkdir_then_interrupt(path: object, *args: object, **kwargs: object) -> None:
        real_mkdir(path, *args, **kwargs)  # type: ignore[arg-type]
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "mkdir", mkdir_then_interrupt)
    with pytest.raises(KeyboardInterrupt), OutputSet() as outputs:
        outputs.stage(tmp_path / "o.rrd")
    monkeypatch.undo()
    assert list(tmp_path.iterdir()) == []


def test_a_staging_folder_that_cannot_be_made_is_not_kept_as_an_output(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def no_space(path: object, *args: object, **kwargs: object) -> None:
        raise OSError(28, "No space left on device")

    outputs = OutputSet()
    monkeypatch.setattr(os, "mkdir", no_space)
    with pytest.raises(OutputError, match="No space left"):
        outputs.stage(tmp_path / "o.json")
    monkeypatch.undo()
    outputs.write_bytes(tmp_path / "o.json", b"{}")  # the same name again: not "used twice"
    outputs.commit()
    assert [p.name for p in tmp_path.iterdir()] == ["o.json"]


def _raise_terminated(signum: int, _frame: object) -> None:
    raise Terminated(signum)


@pytest.fixture
def sigterm_raises() -> Iterator[None]:
    """SIGTERM raises Terminated, as under the CLIs' install_signal_handlers; every handler this
    test changes is put back."""
    names = ("SIGINT", "SIGTERM", "SIGHUP")
    previous = {name: signal.getsignal(getattr(signal, name)) for name in names}
    signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        for name, handler in previous.items():
            signal.signal(getattr(signal, name), handler)


def _sigterm_after_first(monkeypatch: pytest.MonkeyPatch, owner: object, name: str) -> None:
    """Send this process SIGTERM right after the first call of ``owner.name`` returns."""
    real = getattr(owner, name)
    calls: list[int] = []

    def then_signal(*args: object, **kwargs: object) -> object:
        result = real(*args, **kwargs)
        calls.append(1)
        if len(calls) == 1:
            os.kill(os.getpid(), signal.SIGTERM)
        return result

    monkeypatch.setattr(owner, name, then_signal)


def test_a_signal_while_outputs_are_placed_restores_every_old_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, sigterm_raises: None
) -> None:
    for name in ("a.json", "b.json"):
        (tmp_path / name).write_bytes(b"old")
    outputs = OutputSet(force=True)
    for name in ("a.json", "b.json"):
        outputs.write_bytes(tmp_path / name, b"new")
    # Right after the old a.json was moved aside, before the commit noted where it went.
    _sigterm_after_first(monkeypatch, Path, "rename")
    with pytest.raises(Terminated):
        outputs.commit()
    monkeypatch.undo()
    files = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert files == {"a.json": b"old", "b.json": b"old"}


@pytest.mark.parametrize("ends_run", [True, False])
def test_a_signal_once_every_output_is_placed_never_undoes_them(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, sigterm_raises: None, ends_run: bool
) -> None:
    import rose.outputs

    (tmp_path / "a.json").write_bytes(b"old")
    outputs = OutputSet(force=True, ends_run=ends_run)
    outputs.write_bytes(tmp_path / "a.json", b"new")
    outputs.write_bytes(tmp_path / "b.json", b"new")
    _sigterm_after_first(monkeypatch, rose.outputs, "_remove_tree")  # clean-up after the commit
    if ends_run:  # a command's outputs: its work is done, the signal is dropped
        outputs.commit()
        assert signal.getsignal(signal.SIGTERM) is _raise_terminated
    else:  # a library caller (a batch looping over recordings) still gets its Ctrl-C
        with pytest.raises(Terminated):
            outputs.commit()
    monkeypatch.undo()
    files = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert files == {"a.json": b"new", "b.json": b"new"}


def test_a_signal_held_while_the_block_fails_is_not_lost(sigterm_raises: None) -> None:
    with pytest.raises(Terminated) as caught, signals_deferred():
        os.kill(os.getpid(), signal.SIGTERM)
        raise OSError("disk full")
    assert isinstance(caught.value.__cause__, OSError)
    assert signal.getsignal(signal.SIGTERM) is _raise_terminated


def test_ignored_signals_stay_ignored(sigterm_raises: None) -> None:
    """nohup ignores SIGHUP, a shell's background job SIGINT: neither may stop the run."""
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    install_signal_handlers()
    assert signal.getsignal(signal.SIGHUP) == signal.SIG_IGN
    with signals_deferred():
        os.kill(os.getpid(), signal.SIGHUP)
    assert signal.getsignal(signal.SIGHUP) == signal.SIG_IGN


def test_terminated_is_a_keyboard_interrupt() -> None:
    assert isinstance(Terminated(signal.SIGHUP), KeyboardInterrupt)
    assert Terminated(signal.SIGHUP).exit_code == 129


@pytest.mark.parametrize(
    ("signum", "raised"), [(signal.SIGTERM, Terminated), (signal.SIGINT, KeyboardInterrupt)]
)
def test_deferred_signals_arrive_after_the_block(signum: int, raised: type[BaseException]) -> None:
    """Start-up imports run to the end; the signal is raised once they are done."""
    finished = False
    with pytest.raises(raised), signals_deferred():
        os.kill(os.getpid(), signum)
        for _ in range(100):  # the handler runs between bytecodes
            math.sqrt(2.0)
        finished = True
    assert finished
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_an_interrupted_import_is_recognised() -> None:
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise ImportError("initialization failed") from None
    except ImportError as err:
        # `from None` only hides the context in tracebacks; the chain still leads to the interrupt
        assert isinstance(interrupt_behind(err), KeyboardInterrupt)
    assert interrupt_behind(ImportError("no module named x")) is None


def test_a_ctrl_c_after_the_work_is_done_changes_nothing(tmp_path: Path) -> None:
    """Outputs committed, the command exits: a late Ctrl-C (here during interpreter shutdown) must
    neither kill it nor print a traceback."""
    script = tmp_path / "late.py"
    script.write_text(
        "import atexit, os, signal, time\n"
        "from rose.signals import exit_after\n"
        "atexit.register(lambda: (os.kill(os.getpid(), signal.SIGINT), time.sleep(0.2)))\n"
        "exit_after(0)\n"
    )
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0
    assert done.stderr == ""


def test_a_storage_file_of_a_bag_protects_the_bag_and_what_it_links_to(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The bag folder of a storage file is protected as well as the file itself (a symlinked
    file's target too), also reached through a link outside the bag or named from inside it."""
    from rose.outputs import enclosing_bag_folder

    data = tmp_path / "data"
    data.mkdir()
    (data / "real.db3").write_bytes(b"sqlite")
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("relative_file_paths:\n- bag_0.db3\n")
    (bag / "bag_0.db3").symlink_to(data / "real.db3")
    (tmp_path / "x.db3").symlink_to(bag / "bag_0.db3")
    for given in (bag / "bag_0.db3", tmp_path / "x.db3"):
        assert enclosing_bag_folder(given) == bag
        outputs = OutputSet(inputs=[given], force=True)
        for target in (data / "real.db3", bag / "metadata.yaml", bag / "nested.mcap"):
            with pytest.raises(OutputError, match="refusing to write"):
                outputs.stage(target)
    monkeypatch.chdir(bag)
    assert enclosing_bag_folder(Path("bag_0.db3")) == bag
    from rose_logs.session import default_output_path

    assert default_output_path(Path("bag_0.db3")) == tmp_path / "bag_0.rose"


def test_a_folder_with_some_other_metadata_yaml_is_no_bag(tmp_path: Path) -> None:
    """A data set folder with its own metadata.yaml: its files are ordinary inputs."""
    from rose.outputs import enclosing_bag_folder

    (tmp_path / "metadata.yaml").write_text("name: my dataset\n")
    (tmp_path / "run.mcap").write_bytes(b"mcap")
    (tmp_path / "map.png").write_bytes(b"png")
    assert enclosing_bag_folder(tmp_path / "run.mcap") is None
    assert enclosing_bag_folder(tmp_path / "map.png") is None
    staged = OutputSet(inputs=[tmp_path / "map.png"]).stage(tmp_path / "clean.yaml")
    assert staged.path == tmp_path / "clean.yaml"


def test_an_empty_folder_is_filled_by_a_folder_output_without_force(tmp_path: Path) -> None:
    """`mkdir out && rose-bag evaluate out` was refused ("exists already (--force replaces
    it)"), though an empty folder holds nothing to overwrite. One filled while the run wrote is
    never moved aside and deleted: the commit fails and the file stays."""
    out = tmp_path / "out"
    out.mkdir()
    out.chmod(0o2770)  # made for the output, shared with a group: filled, it keeps its mode
    with OutputSet() as outputs:
        staged = outputs.stage(out, directory=True)
        assert staged.temp is not None
        staged.temp.mkdir()
        (staged.temp / "a.txt").write_text("new")
    assert [p.name for p in out.iterdir()] == ["a.txt"]
    assert stat.S_IMODE(out.stat().st_mode) == 0o2770
    again = tmp_path / "again"
    again.mkdir()
    outputs = OutputSet()
    staged = outputs.stage(again, directory=True)
    assert staged.temp is not None
    staged.temp.mkdir()
    (again / "notes.txt").write_text("mine")  # put there while the run wrote
    with pytest.raises(OutputError, match="again: got files while writing, not replacing it"):
        outputs.commit()
    assert [p.name for p in again.iterdir()] == ["notes.txt"]
    # With --force too: it licenses replacing a folder checked as replaceable (an earlier
    # report), and the empty one was; the file put in it meanwhile was deleted with it.
    (again / "notes.txt").unlink()
    outputs = OutputSet(force=True)
    staged = outputs.stage(again, directory=True, replaceable=lambda p: (p / "r.md").exists())
    assert staged.temp is not None
    staged.temp.mkdir()
    (staged.temp / "r.md").write_text("report")
    (again / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match="again: got files while writing, not replacing it"):
        outputs.commit()
    assert [p.name for p in again.iterdir()] == ["notes.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["again", "out"]  # no temporaries left
    # A set that fails after the folder was filled leaves it empty again, as it was.
    last = tmp_path / "last"
    last.mkdir()
    last.chmod(0o2750)  # a group's folder: it keeps its mode, filled or put back
    outputs = OutputSet()
    staged = outputs.stage(last, directory=True)
    assert staged.temp is not None
    staged.temp.mkdir()
    outputs.write_bytes(tmp_path / "f.txt", b"new")
    (tmp_path / "f.txt").write_text("mine")  # appears while the run writes: the set fails
    with pytest.raises(OutputError, match=r"f\.txt: appeared while writing"):
        outputs.commit()
    assert last.is_dir() and not any(last.iterdir())
    assert stat.S_IMODE(last.stat().st_mode) == 0o2750
    assert (tmp_path / "f.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["again", "f.txt", "last", "out"]


def test_an_empty_folder_this_user_may_not_write_in_is_not_filled(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An empty folder without write permission (`chmod a-w out`) was filled all the same: the
    rename into its parent replaced it, and (since it keeps the folder's mode) left a read-only
    folder whose report the undo of a failed set could not remove."""
    out = tmp_path / "out"
    out.mkdir()
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: Path(p) != out and real(p, mode))
    with pytest.raises(OutputError, match=r"out: folder not writable \(permission denied\)"):
        OutputSet().stage(out, directory=True)
    assert [p.name for p in tmp_path.iterdir()] == ["out"]


def test_an_output_that_cannot_be_placed_is_named_as_given(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A rename that failed at commit (EBUSY: a bind-mounted folder, EXDEV, EACCES) was reported
    with the rename's source, the hidden temporary ('.../.out.rose-tmp-<tag>-<pid>-<random>/out:
    cannot commit the outputs ...'): the output is named as the user gave it."""
    outputs = OutputSet()
    staged = outputs.stage(tmp_path / "out", directory=True)
    assert staged.temp is not None
    staged.temp.mkdir()

    def busy(self: Path, target: Path) -> None:
        raise OSError(errno.EBUSY, "Device or resource busy", str(self), str(target))

    monkeypatch.setattr(Path, "rename", busy)
    with pytest.raises(OutputError) as raised:
        outputs.commit()
    assert (
        str(raised.value)
        == f"{tmp_path / 'out'}: cannot commit the outputs (Device or resource busy)"
    )


def test_a_folder_output_never_replaces_the_current_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`mkdir o && cd o && rose-bag evaluate . --logs '' --maps ''` renamed the report onto the
    empty current folder: the shell was left in a deleted folder (`ls` empty), the report beside
    it. The current folder, or one that holds it (an earlier report with --force), is refused."""
    here = tmp_path / "o"
    here.mkdir()
    monkeypatch.chdir(here)
    for given in (".", here):
        with pytest.raises(OutputError, match="is the current folder or holds it"):
            OutputSet().stage(given, directory=True)
    report = tmp_path / "report"
    (report / "figures").mkdir(parents=True)
    monkeypatch.chdir(report / "figures")
    with pytest.raises(OutputError, match=r"^\.\.: is the current folder or holds it"):
        OutputSet(force=True).stage("..", directory=True, replaceable=lambda _: True)
    assert here.is_dir() and (report / "figures").is_dir()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o", "report"]  # no temporaries


def test_a_folder_output_never_replaces_a_mount_point(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`rose-bag evaluate /mnt/usb` on an empty mounted drive ran every experiment, then failed to
    rename the report onto the mount point, naming its temporary ('.../.usb.rose-tmp-.../usb:
    cannot commit the outputs (Device or resource busy)'). Refused before the work now."""
    usb = tmp_path / "usb"
    usb.mkdir()
    real = os.path.ismount
    monkeypatch.setattr(os.path, "ismount", lambda p: Path(p) == usb or real(p))
    with pytest.raises(OutputError, match=r"usb: is a mount point, not replacing it"):
        OutputSet().stage(usb, directory=True)
    assert [p.name for p in tmp_path.iterdir()] == ["usb"]


def test_force_never_replaces_a_folder_whose_metadata_yaml_is_another_tools(
    tmp_path: Path,
) -> None:
    """`process LOG -o data --format db3 --force` deleted a data set folder whose own
    metadata.yaml listed its files: they were taken for the bag's, though is_bag_folder says
    such a folder is no bag."""
    from rose.outputs import is_bag_folder

    data = tmp_path / "data"
    data.mkdir()
    (data / "metadata.yaml").write_text("name: office scans\nfiles:\n- a.csv\n- b.csv\n")
    for name in ("a.csv", "b.csv"):
        (data / name).write_text("1,2\n")
    assert not is_bag_folder(data)
    with pytest.raises(OutputError, match="is a directory that is not a ROS 2 bag"):
        OutputSet(force=True).stage(data, directory=True)
    assert sorted(p.name for p in data.iterdir()) == ["a.csv", "b.csv", "metadata.yaml"]
    # A bag whose metadata.yaml is damaged (rosbag2's key lost) but names its storage file
    # beside it is still one: replaceable.
    (data / "metadata.yaml").write_text("relative_file_paths:\n- data_0.db3\n")
    for name in ("a.csv", "b.csv"):
        (data / name).unlink()
    (data / "data_0.db3").write_bytes(b"db3")
    assert is_bag_folder(data)
    outputs = OutputSet(force=True)
    outputs.stage(data, directory=True)
    outputs.abort()


def test_a_fifo_named_metadata_yaml_is_no_bag_and_never_read(tmp_path: Path) -> None:
    """`process bag/x.db3` (its metadata.yaml a FIFO) and `process LOG -o DIR --format db3
    --force` (DIR/metadata.yaml a FIFO) hung for ever opening the FIFO to read it."""
    import threading

    from rose.outputs import enclosing_bag_folder, is_bag_folder

    bag = tmp_path / "bag"
    bag.mkdir()
    os.mkfifo(bag / "metadata.yaml")
    (bag / "x.db3").write_bytes(b"db3")
    answers: list[object] = []

    def judge() -> None:
        answers.append(enclosing_bag_folder(bag / "x.db3"))
        answers.append(is_bag_folder(bag))
        try:
            OutputSet(force=True).stage(bag, directory=True)
        except OutputError as err:
            answers.append(str(err))

    thread = threading.Thread(target=judge, daemon=True)
    thread.start()
    thread.join(timeout=10)
    assert not thread.is_alive(), "blocked on the FIFO"
    assert answers == [
        None,
        False,
        f"{bag}: is a directory that is not a ROS 2 bag, not replacing it",
    ]


def test_bag_folders_are_told_where_os_has_no_o_nonblock(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Windows has no os.O_NONBLOCK: every output's bag-folder check (rose clean -o, process
    --json, ...) failed there with an AttributeError since metadata.yaml was opened with it."""
    from rose.outputs import enclosing_bag_folder, is_bag_folder

    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information:\n  files: [bag_0.db3]\n")
    (bag / "bag_0.db3").write_bytes(b"db3")
    monkeypatch.delattr(os, "O_NONBLOCK")
    assert is_bag_folder(bag)
    assert not is_bag_folder(tmp_path)
    assert enclosing_bag_folder(bag / "bag_0.db3") == bag
    with pytest.raises(OutputError, match="inside the ROS 2 bag folder"):
        refuse_output_in_bag_folder(bag / "out.json", "--json")


def test_an_output_under_a_file_says_the_file_is_no_folder(tmp_path: Path) -> None:
    """'notes.txt/out.json' said 'folder notes.txt does not exist'; it does, as a file."""
    (tmp_path / "notes.txt").write_text("x")
    for call in (OutputSet().check, OutputSet().stage):
        with pytest.raises(OutputError, match=r"notes\.txt is a file, not a folder"):
            call(tmp_path / "notes.txt" / "out.json")
    with pytest.raises(OutputError, match=r"folder .*missing does not exist"):
        OutputSet().stage(tmp_path / "missing" / "out.json")
    # Deeper under the file too (`evaluate notes.txt/a/report`): said the folder notes.txt/a
    # did not exist, as if making it would do.
    for call in (OutputSet().check, OutputSet().stage):
        with pytest.raises(OutputError, match=r"notes\.txt is a file, not a folder"):
            call(tmp_path / "notes.txt" / "a" / "b" / "out.json", directory=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


def test_the_longest_output_name_stages_under_a_long_host_name(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A name that passed the check failed when staged ("File name too long") once the temporary's
    name held a long host name (a cloud host's FQDN, a Kubernetes pod)."""
    import socket

    from rose import outputs

    monkeypatch.setattr(socket, "gethostname", lambda: "ip-10-0-0-1.eu-west-1.compute.internal.x")
    assert len(process_tag()) <= outputs._MAX_TAG_CHARS
    longest = "n" * (outputs._MAX_OUTPUT_NAME_BYTES - len(".json")) + ".json"
    written = OutputSet()
    written.write_bytes(tmp_path / longest, b"{}")
    written.commit()
    assert (tmp_path / longest).read_bytes() == b"{}"
    with pytest.raises(OutputError, match="output file name longer than"):
        OutputSet().write_bytes(tmp_path / ("n" + longest), b"{}")


def test_counts_are_said_in_the_singular_for_one() -> None:
    """`convert` printed "1 scans, 1 maps" and `rose walls` "1 walls"."""
    assert [counted(n, "scan") for n in (0, 1, 2)] == ["0 scans", "1 scan", "2 scans"]


@pytest.mark.skipif(
    sys.platform != "linux" or os.geteuid() != 0 or shutil.which("setpriv") is None,
    reason="needs root and setpriv to run a non-root process with CAP_DAC_OVERRIDE",
)
def test_the_writable_check_asks_with_the_ids_writing_uses(tmp_path: Path) -> None:
    """A non-root process with CAP_DAC_OVERRIDE (a container's user given it) may write in a
    root-owned 0755 folder, but access() by the real ids said no: its outputs were refused as
    'not writable' before any work, though writing them succeeds."""
    import rose

    folder = tmp_path / "root_owned"
    folder.mkdir(mode=0o755)
    code = (
        "import sys; from rose.outputs import OutputSet; "
        "OutputSet().check(sys.argv[1]); open(sys.argv[1], 'w').write('ok')"
    )
    done = subprocess.run(
        [
            "setpriv",
            "--reuid=65534",
            "--regid=65534",
            "--clear-groups",
            "--inh-caps=+dac_override",
            "--ambient-caps=+dac_override",
            sys.executable,
            "-c",
            code,
            str(folder / "out.json"),
        ],
        env={**os.environ, "PYTHONPATH": str(Path(rose.__file__).parents[1])},
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    if "setpriv:" in done.stderr:  # no capabilities to hand on (a restricted container)
        pytest.skip(done.stderr.strip())
    assert done.returncode == 0, done.stderr
    assert (folder / "out.json").read_text() == "ok"
