"""`./run test` keeps the tests of one xdist group on one worker (`--dist loadgroup`)."""

import ast
from pathlib import Path

import pytest

pytestmark = pytest.mark.xdist_group("xdist_groups_check")


def test_a_grouped_test_carries_its_group_under_loadgroup(request):
    """pytest 9.2 stopped pytest-xdist 3.8 from suffixing node ids with their group, and the
    groups (real-time CAN tests, module-scoped episodes) were then spread over workers."""
    if not getattr(request.config.option, "loadgroup", False):
        pytest.skip("not run by an xdist worker with --dist loadgroup")
    assert request.node.nodeid.endswith("@xdist_groups_check")


def test_no_test_module_assigns_its_pytestmark_twice():
    """A second `pytestmark = ...` silently drops the first one's marks and group (as
    test_can_link.py once lost its `realtime` group and `emulated_hardware` mark)."""
    twice = []
    for path in sorted(Path(__file__).parent.glob("test_*.py")):
        names = [target.id for node in ast.parse(path.read_text()).body
                 if isinstance(node, ast.Assign | ast.AnnAssign)
                 for target in (node.targets if isinstance(node, ast.Assign) else [node.target])
                 if isinstance(target, ast.Name)]
        if names.count("pytestmark") > 1:
            twice.append(path.name)
    assert twice == []
