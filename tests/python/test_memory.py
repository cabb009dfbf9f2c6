"""No memory growth over 1000 plans (RSS from /proc/self/statm)."""
import os

import refdyn
from conftest import MINIMAL_YAML


def rss_bytes():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def test_no_memory_growth_over_1000_plans():
    text = MINIMAL_YAML.read_text().replace("t1: 0.5", "t1: 0.02")
    assert "t1: 0.02" in text
    problem = refdyn.loads(text, str(MINIMAL_YAML))

    def once(i):
        plan = refdyn.plan(problem if i % 2 else text)   # a built problem and a parse every other time
        assert plan.ok and plan.data.shape[0] == 21

    for i in range(100):  # warm-up: allocator pools, caches
        once(i)
    before = rss_bytes()
    for i in range(1000):
        once(i)
    growth = rss_bytes() - before
    print(f"RSS growth over 1000 plans: {growth / 1024:.0f} KiB")
    assert growth < 4 * 1024 * 1024, f"RSS grew by {growth / 1024:.0f} KiB over 1000 plans"


def test_no_memory_growth_over_check_and_run_variants_calls():
    # refdyn.check and refdyn.run_variants with a progress callable (Python objects held across
    # the released GIL): no growth over 300 calls of each.
    text = MINIMAL_YAML.read_text().replace("t1: 0.5", "t1: 0.02")
    family = text + "\nvariants:\n  name: \"L{L1}\"\n  grid: {L1: [0.5, 0.55]}\n"
    seen = []

    def once():
        assert refdyn.check(text)["valid"]
        r = refdyn.run_variants(family, progress=lambda done, total, name: seen.append(done))
        assert r.ok and len(r) == 2

    for _ in range(50):  # warm-up
        once()
    before = rss_bytes()
    for _ in range(300):
        once()
    growth = rss_bytes() - before
    print(f"RSS growth over 300 checks and variant runs: {growth / 1024:.0f} KiB")
    assert len(seen) == 2 * 350
    assert growth < 4 * 1024 * 1024, f"RSS grew by {growth / 1024:.0f} KiB over 300 checks and variant runs"
