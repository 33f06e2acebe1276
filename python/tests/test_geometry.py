"""Each pad's role and geometry as the device reports them: the simulated glove's palm has
12 mm x 8 mm electrodes (96 mm²) where its fingertips have the article's 5 mm ones, and its force is
its pressures over those areas."""

import numpy as np
import pytest

import taxel


def test_pad_info_gives_each_pads_role_and_geometry_and_the_force_uses_it() -> None:
    with taxel.Simulator(scene="glove", speed=5.0) as device:
        assert device.pads == 6
        palm = device.pad_info(5)
        assert palm["role"] == "palm"
        assert palm["taxels"].shape == (4, 3)
        np.testing.assert_array_equal(palm["taxels"][:, 2], [96.0] * 4)
        np.testing.assert_array_equal(palm["taxels"][0, :2], [-6.5, 4.5])
        thumb = device.pad_info(0)
        assert thumb["role"] == "fingertip"
        np.testing.assert_array_equal(thumb["taxels"][:, 2], [25.0] * 4)
        with pytest.raises(taxel.LinkError, match="no pad 6"):
            device.pad_info(6)
        # The palm's force is its pressures times 96 mm² (kPa x mm² / 1000 = N).
        compared = 0
        for _ in range(600):
            sample = device.read()
            pressures = sample.pressure_kpa[20:24]  # pad 5's four taxels
            force = sample.force_n[5]
            if np.isnan(force) or np.isnan(pressures).any() or force < 0.5:
                continue
            assert force == pytest.approx(float(np.sum(pressures) * 96.0 / 1000.0), rel=1e-4)
            compared += 1
            if compared >= 20:
                break
        assert compared >= 20
