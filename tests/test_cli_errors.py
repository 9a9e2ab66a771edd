"""The command line as a user first meets it: a bad input ends in one line on stderr and exit
code 2 (never a traceback), help reads cleanly at 80 columns, and --version answers."""

from __future__ import annotations

import re

import pytest

from physcap_drake.cli import app, main
from physcap_drake.recording import topics
from physcap_drake.recording.mcap_sink import McapSink
from physcap_drake.resources import agents_dir, stations_dir

SCENARIO = str(stations_dir() / "piper_table.yaml")
CAN_SCENE = str(stations_dir() / "identify_empty_can.yaml")
NOT_A_SCENARIO = str(agents_dir() / "physcap.yaml")  # YAML, but an agent variant
README = str(agents_dir() / "README.md")  # not YAML, not MCAP, not JSON Lines


def run_cli(capsys, argv: list[str]) -> tuple[int, str, str]:
    """Runs `physcap argv` in this process, as the console script does."""
    with pytest.raises(SystemExit) as done:
        main(argv)
    out, err = capsys.readouterr()
    return done.value.code, out, err


@pytest.fixture(scope="module")
def other_mcap(tmp_path_factory):
    """An MCAP file that is not an episode recording."""
    path = tmp_path_factory.mktemp("mcap") / "other.mcap"
    sink = McapSink(path)
    sink.json(topics.AGENT_PROGRESS, 0.0, {"phase": "idle", "steps": 0, "oi": 0, "note": ""})
    sink.close()
    return str(path)


# (arguments, a phrase the error must contain); {missing}, {mcap} are filled in per test.
BAD_INPUTS = [
    # missing files
    (["run", "--task", "identify_empty_can", "--llm", "replay:{missing}"], "no such file"),
    (["run", "--task", "identify_empty_can", "--scenario", "{missing}"], "no such file"),
    (["replay", "{missing}"], "no recording at"),
    (["recover", "{missing}"], "no recording at"),
    (["sim", "--scenario", "{missing}"], "no such file"),
    (["demo", "pick-place", "--scenario", "{missing}"], "no such file"),
    (["emulate-piper", "--channel", "x", "--interface", "virtual", "--scenario", "{missing}"],
     "no such file"),
    (["eval", "--llm", "replay:{missing}", "--out", "{missing}"], "no such file"),
    (["compare", "{missing}", "{missing}"], "no evaluation folder"),
    # files of the wrong kind
    (["run", "--task", "identify_empty_can", "--llm", "replay:" + README], "not a call record"),
    (["run", "--task", "identify_empty_can", "--llm", "replay:{mcap}"], "not a JSON Lines"),
    (["run", "--task", "identify_empty_can", "--scenario", NOT_A_SCENARIO], "are not known"),
    (["run", "--task", "identify_empty_can", "--out", README], "is a file"),
    (["replay", README], "is not an MCAP recording"),
    (["replay", "{mcap}"], "physcap.episode"),
    (["recover", README], "is not an MCAP recording"),
    (["compare", "tests", "tests"], "holds no finished episode"),
    (["sim", "--scenario", NOT_A_SCENARIO], "are not known"),
    (["sim", "--scenario", README], "README.md"),
    (["demo", "pick-place", "--scenario", NOT_A_SCENARIO], "are not known"),
    (["emulate-piper", "--channel", "x", "--interface", "virtual", "--scenario", README],
     "README.md"),
    # scenarios (and names) that do not fit
    (["run", "--task", "find_blue_cube", "--scenario", CAN_SCENE], "task.name"),
    (["run", "--task", "identify_empty_can", "--scenario", SCENARIO], "names no task"),
    (["demo", "pick-place", "--scenario", CAN_SCENE], "'soda_can' missing"),
    (["run", "--task", "no_such_task"], "unknown task"),
    (["run", "--task", "identify_empty_can", "--agent", "nope"], "unknown agent variant"),
    (["run", "--task", "identify_empty_can", "--perception", "lidar"],
     "--perception 'lidar' is not one of rgbd, label"),
    (["run", "--task", "identify_empty_can", "--judge", "nobody"],
     "--judge 'nobody' is not one of simulator, perception, operator"),
    (["run", "--task", "identify_empty_can", "--llm", "gemini", "--vertex-project", "p"],
     "--vertex-location is missing"),
    (["task", "show", "no_such_task"], "unknown task"),
    (["task", "check", "identify_empty_can", "--seeds", "a-b"], "--seeds"),
    (["eval", "--agents", "physcap,oracle"], "unknown agent variant"),
    # mistyped command lines
    (["run", "--task"], "--task"),
    (["run", "--task", "identify_empty_can", "--seed", "-1"], "--seed"),
    (["bench", "pick-place", "--trials", "0"], "--trials"),
    (["calibrate", "mass", "--bogus"], "--bogus"),
    (["no-such-command"], "no-such-command"),
]


@pytest.mark.parametrize(("argv", "phrase"), BAD_INPUTS,
                         ids=[" ".join(a[:3]) + f" [{i}]" for i, (a, _) in enumerate(BAD_INPUTS)])
def test_bad_input_is_one_line_on_stderr_and_exit_2(capsys, tmp_path, other_mcap, argv, phrase):
    filled = [a.format(missing=tmp_path / "missing.file", mcap=other_mcap) for a in argv]
    code, out, err = run_cli(capsys, filled)
    assert code == 2, (out, err)
    assert "Traceback" not in out + err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert phrase in lines[0], lines[0]


def test_version(capsys):
    code, out, _ = run_cli(capsys, ["--version"])
    assert code == 0
    assert re.fullmatch(r"physcap \d+\.\d+\.\d+\S* \(drake 1\.\d+\.\d+, Python 3\.\d+\.\d+, "
                        r"allocator (tcmalloc|system), BLAS threads (\d+|unknown)\)\n",
                        out), out


def _command_paths(group, prefix=()):
    for name, command in group.commands.items():
        yield (*prefix, name)
        if hasattr(command, "commands"):
            yield from _command_paths(command, (*prefix, name))


def test_every_help_reads_cleanly_at_80_columns(capsys):
    import typer.main

    paths = [(), *_command_paths(typer.main.get_command(app))]
    assert ("recover",) in paths and ("task", "check") in paths
    for path in paths:
        code, out, err = run_cli(capsys, [*path, "--help"])
        assert code == 0 and not err, path
        lines = out.splitlines()
        assert lines[0].startswith("Usage: physcap"), path
        assert max(len(line) for line in lines) <= 80, (path, max(lines, key=len))
        assert "<bool>" not in out and "\x1b[" not in out, path
        listed = re.findall(r"^  (\S+)\s{2,}(.+)$", out.split("Commands:")[-1], re.M) \
            if "Commands:" in out else []
        for name, summary in listed:
            assert not summary.endswith("..."), (path, name, summary)  # whole first sentences


def test_no_arguments_show_the_help(capsys):
    code, out, _ = run_cli(capsys, [])
    assert code == 0 and "Commands:" in out and "recover" in out
