"""The packages depend one way: orbit_sim <- radar_sensor <- tracker_filters (as their package.xml declare).

Importing a lower package must not load a higher one; the launcher reaches the sensor and filter packages
only through the module names in the graph's node specs.
"""
import subprocess
import sys

import pytest

LOWER = {
    "orbit_sim": ["bench_engine.launcher", "bench_engine.graph", "orbit_sim.truth", "orbit_sim.angles"],
    "radar_sensor": ["bench_models.radar", "bench_models.isl", "radar_sensor.sensor"],
}
HIGHER = {"orbit_sim": ("radar_sensor", "tracker_filters"), "radar_sensor": ("tracker_filters",)}


@pytest.mark.parametrize("package", sorted(LOWER))
def test_a_package_loads_nothing_from_the_packages_that_depend_on_it(package):
    code = ("import sys\n" + "".join(f"import {m}\n" for m in LOWER[package])
            + "print(' '.join(sorted({m.split('.')[0] for m in sys.modules})))")
    loaded = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    top_level = set(loaded.stdout.split())
    assert package in top_level
    assert not top_level & set(HIGHER[package]), f"{package} loads {top_level & set(HIGHER[package])}"
