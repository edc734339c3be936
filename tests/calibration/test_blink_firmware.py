"""The blinking test luminaire's firmware (vlp-calibrate --blink-firmware): its timer setting, and the C it
writes built with avr-gcc and run on simavr, its LED pin toggling at the rate it claims."""

import json
import subprocess
import time

import numpy as np
import pytest

from conftest import vlp
from planner.calibration.blink import blink_timer
from planner.errors import UsageError


@pytest.mark.parametrize("hz,prescaler,compare", [(1000, 1, 7999), (777, 1, 10295), (100, 8, 9999), (2, 64, 62499)])
def test_the_timer_setting_is_the_finest_that_fits(hz, prescaler, compare):
    timer = blink_timer(hz, 16e6)
    assert (timer.prescaler, timer.compare) == (prescaler, compare)
    assert timer.actual_hz == pytest.approx(hz, rel=1e-4)


def test_rates_the_timer_cannot_make_are_refused():
    for hz in (50_000.0, 0.05):
        with pytest.raises(UsageError, match="`blink_hz`"):
            blink_timer(hz, 16e6)


@pytest.mark.needs_avr
@pytest.mark.parametrize("hz", [1000.0, 777.0])
def test_the_firmware_blinks_at_its_rate_on_simavr(tmp_path, hz):
    from planner.flash.avr.build import AVR_FLAGS, build_harness
    from planner.flash.avr.trace import read_vcd

    done = vlp("vlp-calibrate", "--blink-firmware", str(tmp_path / "fw"), "--blink-hz", str(hz), "--json")
    assert done.returncode == 0, done.stderr
    claimed = json.loads(done.stdout)["blink_firmware"]["blink_hz"]
    elf = tmp_path / "blink.elf"
    built = subprocess.run(["avr-gcc", *AVR_FLAGS, str(tmp_path / "fw" / "blink.c"), "-o", str(elf)],
                           capture_output=True, text=True, timeout=60)
    assert built.returncode == 0, built.stderr  # -Wall -Wextra -Werror, as the driver firmware
    eeprom = tmp_path / "eeprom.bin"
    eeprom.write_bytes(b"\xff" * 1024)
    trace = tmp_path / "led.vcd"
    mcu = subprocess.Popen([str(build_harness()), str(elf), str(eeprom), str(trace)], stdin=subprocess.PIPE,
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    time.sleep(0.3)  # simulated time follows the wall clock while the MCU sleeps between toggles
    assert mcu.stdin is not None
    mcu.stdin.close()  # end of input: the harness stops
    assert mcu.wait(timeout=30) == 0
    times, levels = read_vcd(trace)
    assert len(times) > 100 and set(levels[:2]) == {0, 1}
    halves = np.diff(times[1:])  # the first edge comes after the start-up code
    assert np.abs(halves - 0.5 / claimed).max() < 1e-9  # every half period exact to the clock cycle
    assert np.all(levels[1:] != levels[:-1])  # it toggles: each edge the other level
