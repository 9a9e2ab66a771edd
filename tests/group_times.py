"""`--group-times`: wall and CPU seconds of the suite summed per xdist group, per tier,
per worker and per test module (the costliest 30); a worker's wall sum is how long it was
busy.

A test's CPU time is its worker's (all threads) plus the child processes it waited for, over
setup, call and teardown. Ungrouped tests sum under "(no group)". See docs/development.md.
"""

from __future__ import annotations

import resource
from collections import defaultdict

import pytest

NO_GROUP = "(no group)"


def pytest_addoption(parser):
    parser.addoption("--group-times", action="store_true",
                     help="print wall and CPU seconds summed per xdist group and per tier")


def _cpu_seconds() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


_started_key = pytest.StashKey[float]()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    before = item.stash.get(_started_key, None)
    outcome = yield
    if item.config.getoption("group_times") and before is not None:
        group = item.get_closest_marker("xdist_group")
        report = outcome.get_result()
        report.user_properties.append(("cpu_s", _cpu_seconds() - before))
        name = (group.args[0] if group.args else group.kwargs["name"]) if group else NO_GROUP
        report.user_properties.append(("group", name))
        report.user_properties.append(("episode", item.get_closest_marker("episode") is not None))


def _stamp(item):
    item.stash[_started_key] = _cpu_seconds()


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    _stamp(item)


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_call(item):
    _stamp(item)


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_teardown(item, nextitem):
    _stamp(item)


class _Sums:
    def __init__(self):
        self.wall, self.cpu, self.tests = defaultdict(float), defaultdict(float), defaultdict(set)

    def add(self, key: str, report) -> None:
        props = dict(report.user_properties)
        self.wall[key] += report.duration
        self.cpu[key] += props.get("cpu_s", 0.0)
        self.tests[key].add(report.nodeid)


_groups, _tiers, _workers, _modules = _Sums(), _Sums(), _Sums(), _Sums()
#: How many test modules the summary lists, the most CPU first.
MODULES_SHOWN = 30


def pytest_runtest_logreport(report):
    props = dict(report.user_properties)
    if "group" not in props:
        return
    _groups.add(props["group"], report)
    _tiers.add("episode" if props["episode"] else "fast tier (not episode)", report)
    worker = getattr(report, "node", None)  # set by xdist's controller
    _workers.add(f"worker {worker.gateway.id}" if worker else "this process", report)
    _modules.add(report.nodeid.split("::")[0], report)


def pytest_terminal_summary(terminalreporter, config):
    if not config.getoption("group_times") or not _groups.wall:
        return
    write = terminalreporter.write_line
    terminalreporter.section("wall and CPU seconds per xdist group, tier and worker")
    for sums in (_groups, _tiers, _workers):
        for key in sorted(sums.wall, key=lambda k: -sums.wall[k]):
            _write_line(write, sums, key)
        write("")
    for key in sorted(_modules.cpu, key=lambda k: -_modules.cpu[k])[:MODULES_SHOWN]:
        _write_line(write, _modules, key)


def _write_line(write, sums: _Sums, key: str) -> None:
    write(f"{sums.wall[key]:8.1f} s wall {sums.cpu[key]:8.1f} s CPU "
          f"{len(sums.tests[key]):5d} tests  {key}")
