"""The allocator `physcap` runs with: TCMalloc by default (restarting itself with it
preloaded), glibc's when asked or when TCMalloc is missing, and a bad choice named."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from physcap_drake import allocator


def _clean_environment(**extra: str) -> dict[str, str]:
    """This process's environment without any allocator choice or preload."""
    environ = {k: v for k, v in os.environ.items()
               if k not in ("LD_PRELOAD", allocator.CHOICE_VARIABLE,
                            allocator.STATE_VARIABLE)}
    return {**environ, **extra}


def _version(**extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "physcap_drake", "--version"],
                          env=_clean_environment(**extra), capture_output=True, text=True,
                          timeout=120)


def test_the_choice_defaults_to_tcmalloc_and_names_a_bad_value():
    assert allocator.choice({}) == "tcmalloc"
    assert allocator.choice({"PHYSCAP_ALLOCATOR": "System"}) == "system"
    assert allocator.choice({"PHYSCAP_ALLOCATOR": ""}) == "tcmalloc"
    with pytest.raises(ValueError, match="PHYSCAP_ALLOCATOR must be one of tcmalloc, "
                                         "system; got 'jemalloc'"):
        allocator.choice({"PHYSCAP_ALLOCATOR": "jemalloc"})


def test_the_restart_puts_tcmalloc_first_in_the_preload_and_keeps_the_rest():
    environ = allocator.restart_environment(
        {"LD_PRELOAD": "libfoo.so:libtcmalloc_minimal.so.4", "HOME": "/h"},
        "libtcmalloc_minimal.so.4")
    assert environ["LD_PRELOAD"] == "libtcmalloc_minimal.so.4 libfoo.so"
    assert environ["HOME"] == "/h" and environ[allocator.STATE_VARIABLE] == "restarted"


def test_the_allocator_in_use_is_read_from_the_process_memory_map(tmp_path):
    maps = tmp_path / "maps"
    maps.write_text("7f00-7f10 r-xp 0 08:01 1 /usr/lib/x86_64-linux-gnu/libc.so.6\n")
    assert allocator.in_use(str(maps)) == "system"
    maps.write_text("7f00-7f10 r-xp 0 08:01 2 /usr/lib/x86_64-linux-gnu/"
                    "libtcmalloc_minimal.so.4.5.10\n")
    assert allocator.in_use(str(maps)) == "tcmalloc"
    assert allocator.in_use(str(tmp_path / "missing")) == "system"


def test_physcap_restarts_itself_with_tcmalloc():
    assert allocator.find_library() is not None, (
        f"{allocator.LIBRARY} is missing: `./run setup` installs {allocator.PACKAGE}")
    done = _version()
    assert done.returncode == 0, done.stderr
    assert "allocator tcmalloc," in done.stdout, done.stdout
    assert done.stderr == ""


def test_physcap_keeps_glibcs_allocator_when_asked():
    done = _version(PHYSCAP_ALLOCATOR="system")
    assert done.returncode == 0, done.stderr
    assert "allocator system," in done.stdout, done.stdout


def test_a_bad_allocator_choice_is_one_error_line_and_exit_2():
    done = _version(PHYSCAP_ALLOCATOR="jemalloc")
    assert done.returncode == 2
    assert done.stderr.strip() == ("error: PHYSCAP_ALLOCATOR must be one of tcmalloc, "
                                   "system; got 'jemalloc'")


def test_a_missing_tcmalloc_is_said_once_and_glibcs_allocator_runs(monkeypatch, capsys):
    monkeypatch.setattr(allocator, "in_use", lambda: "system")
    monkeypatch.setattr(allocator, "find_library", lambda: None)
    monkeypatch.setattr(os, "execve", lambda *args: pytest.fail("must not restart"))
    monkeypatch.delenv(allocator.CHOICE_VARIABLE, raising=False)
    monkeypatch.delenv(allocator.STATE_VARIABLE, raising=False)
    allocator.use_tcmalloc()
    err = capsys.readouterr().err
    assert err == ("physcap: libtcmalloc_minimal.so.4 not found (install "
                   "libtcmalloc-minimal4); running with glibc's allocator, about a sixth "
                   "slower (set PHYSCAP_ALLOCATOR=system to say that is meant)\n")
    assert os.environ[allocator.STATE_VARIABLE] == "said"  # its child processes say nothing
    allocator.use_tcmalloc()
    assert capsys.readouterr().err == ""


def test_the_restart_runs_the_same_command_line_with_the_library_preloaded(monkeypatch):
    started = []
    monkeypatch.setattr(allocator, "in_use", lambda: "system")
    monkeypatch.setattr(allocator, "find_library", lambda: "libtcmalloc_minimal.so.4")
    monkeypatch.setattr(os, "execve", lambda *args: started.append(args))
    monkeypatch.delenv(allocator.CHOICE_VARIABLE, raising=False)
    monkeypatch.delenv(allocator.STATE_VARIABLE, raising=False)
    monkeypatch.setenv("LD_PRELOAD", "libfoo.so")
    allocator.use_tcmalloc()
    [(executable, argv, environ)] = started
    assert executable == sys.executable and argv == sys.orig_argv
    assert environ["LD_PRELOAD"] == "libtcmalloc_minimal.so.4 libfoo.so"
