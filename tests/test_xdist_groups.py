"""`./run test` keeps the tests of one xdist group on one worker (`--dist loadgroup`)."""

import pytest

pytestmark = pytest.mark.xdist_group("xdist_groups_check")


def test_a_grouped_test_carries_its_group_under_loadgroup(request):
    """pytest 9.2 stopped pytest-xdist 3.8 from suffixing node ids with their group, and the
    groups (real-time CAN tests, module-scoped episodes) were then spread over workers."""
    if not getattr(request.config.option, "loadgroup", False):
        pytest.skip("not run by an xdist worker with --dist loadgroup")
    assert request.node.nodeid.endswith("@xdist_groups_check")
