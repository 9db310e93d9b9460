"""Output options checked before the work starts (issue 39): for every command that takes `--out`
(and `view --html`), a dangling symbolic link, a folder that takes no new files, a file where a
folder goes (or the reverse) is an InputError naming the option, exit 2, and the command's work
never starts. Before, these were found after planning, with a bare errno message."""

import argparse
import os

import pytest

from pickplan.cli.exit_codes import ExitCode, OutputKind, run_command
from pickplan.cli.main import build_parser
from pickplan.cli.main import main as cli_main


def _leaf_parsers(parser, prefix=()):
    """(command words, parser) of every runnable command."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield prefix, parser
        return
    for name, p in subs[0].choices.items():
        yield from _leaf_parsers(p, prefix + (name,))


OUT_COMMANDS = [(words, p) for words, p in _leaf_parsers(build_parser()) if "--out" in p._option_string_actions]


def test_the_commands_that_write_are_all_covered():
    names = {" ".join(w) for w, _ in OUT_COMMANDS}
    assert {
        "demo",
        "plan",
        "scenes",
        "observe",
        "bench planners",
        "bench perception",
        "metamodel build",
        "pickup plan",
        "pickup problems",
        "pickup cases",
    } <= names, names


def _unwritable_folder(tmp_path) -> str:
    """A folder that takes no new files: permission bits for a user; root ignores those, but not /proc's."""
    if os.geteuid() == 0:
        return "/proc"
    folder = tmp_path / "read_only"
    folder.mkdir()
    folder.chmod(0o500)
    return str(folder)


def _bad_outputs(tmp_path, kind):
    link = tmp_path / "dangling"
    link.symlink_to(tmp_path / "nowhere" / "at_all")
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    bad = {
        "dangling symlink": (str(link), "is a symbolic link to"),
        "unwritable": (os.path.join(_unwritable_folder(tmp_path), "out", "result"), "does not take new files"),
        "under a file": (str(a_file / "sub"), "is a file"),
    }
    if kind is OutputKind.folder:
        bad["a file for a folder"] = (str(a_file), "is a file; expected a folder")
    else:
        bad["a folder for a file"] = (str(tmp_path), "is a folder; expected a file")
    return bad


@pytest.mark.parametrize("words, parser", OUT_COMMANDS, ids=[" ".join(w) for w, _ in OUT_COMMANDS])
def test_a_bad_out_is_refused_before_the_work_starts(tmp_path, capsys, words, parser):
    defaults = {a.dest: a.default for a in parser._actions if a.dest != "help"}
    kind = parser.get_default("out_kind") or OutputKind.folder
    started = []
    for case, (out, words_expected) in _bad_outputs(tmp_path, kind).items():
        args = argparse.Namespace(**{**defaults, **parser._defaults, "out": out})
        code = run_command(" ".join(words), lambda a: started.append(a), args)
        err = capsys.readouterr().err
        assert code == ExitCode.BAD_INPUT and "error: --out: " in err, (case, err)
        assert words_expected in err and "Errno" not in err, (case, err)
    assert not started


def test_a_good_out_passes_and_leaves_nothing_behind(tmp_path):
    for words, parser in OUT_COMMANDS:
        kind = parser.get_default("out_kind") or OutputKind.folder
        out = tmp_path / "new" / ("result.npz" if kind is OutputKind.file else "folder")
        args = argparse.Namespace(
            **{**{a.dest: a.default for a in parser._actions}, **parser._defaults, "out": str(out)}
        )
        assert run_command(" ".join(words), lambda a: 0, args) == ExitCode.OK
    assert os.listdir(tmp_path) == []  # the check writes nothing (a probe file, removed)


def test_view_html_is_checked_too(tmp_path, capsys):
    link = tmp_path / "page.html"
    link.symlink_to(tmp_path / "missing" / "page.html")
    assert cli_main(["view", str(tmp_path), "--html", str(link)]) == 2
    assert f"--html: '{link}' is a symbolic link" in capsys.readouterr().err


def test_scenes_with_a_dangling_out_exits_2_at_once(tmp_path, capsys):
    link = tmp_path / "scenes"
    link.symlink_to(tmp_path / "gone")
    assert cli_main(["scenes", "--n", "1", "--out", str(link)]) == 2
    err = capsys.readouterr().err
    assert f"pickplan scenes: error: --out: '{link}' is a symbolic link to '{tmp_path / 'gone'}'" in err
    assert not (tmp_path / "gone").exists()
