"""Table II over the unstated parameters: settings, the campaign per setting, the range."""

from __future__ import annotations

from pathlib import Path

import pytest

from pytest_metamorphic import InvalidArgument
from pytest_metamorphic.driving.sensitivity import (
    RANGES,
    Setting,
    format_sensitivity,
    sensitivity_campaign,
    sensitivity_settings,
)
from pytest_metamorphic.driving.vehicle import EURO_NCAP_CAR, TYPICAL_CAR
from pytest_metamorphic.reports.aeb_campaign import main


def test_settings_vary_one_parameter_at_a_time_around_the_defaults() -> None:
    settings = sensitivity_settings()
    assert settings[0].name == "default"
    assert (settings[0].initial_ttc, settings[0].vehicle) == (6.0, TYPICAL_CAR)
    # Every value of every range except the default's own, plus the ideal car.
    expected = sum(len(values) - 1 for values in RANGES.values()) + 2
    assert len(settings) == expected == 14
    names = [s.name for s in settings]
    assert "start 2 s" in names and "brake delay 0.3 s" in names
    assert "deceleration 8 m/s^2" in names and "latency 0.2 s" in names
    assert settings[-1].vehicle == EURO_NCAP_CAR
    by_name = {s.name: s for s in settings}
    assert by_name["brake delay 0.3 s"].vehicle.max_deceleration == 9.0
    assert by_name["start 3 s"].vehicle == TYPICAL_CAR
    with pytest.raises(InvalidArgument, match="unknown parameter 'friction'"):
        sensitivity_settings(ranges={"friction": (0.5,)})
    with pytest.raises(InvalidArgument, match="not a number"):
        sensitivity_settings(ranges={"brake_delay": ("slow",)})  # type: ignore[dict-item]
    with pytest.raises(InvalidArgument, match="brake_delay"):
        sensitivity_settings(ranges={"brake_delay": (-0.1,)})


def test_the_fault_shows_in_every_setting_and_the_correct_controllers_stay_clean(
    shared_data: Path,
) -> None:
    """Three settings at the speeds where the car is early (23-27 km/h) and a few fast
    ones: the mutant has avoidable violations on every source in each, the reference and
    the TTC AEB none."""
    settings = [
        Setting("default", 6.0, TYPICAL_CAR),
        Setting("start 3 s", 3.0, TYPICAL_CAR),
        Setting("ideal car", 6.0, EURO_NCAP_CAR),
    ]
    speeds = (23, 24, 25, 26, 27, 50, 62, 80)
    results = sensitivity_campaign(shared_data, settings=settings, speeds_kmh=speeds)
    assert [r.setting.name for r in results] == ["default", "start 3 s", "ideal car"]
    for result in results:
        assert len(result.rows) == 9
        for row in result.rows:
            if row.controller == "3.6 m lane mutant":
                assert row.avoidable_violations, (result.setting.name, row.source)
            else:
                assert row.avoidable_violations == (), (result.setting.name, row.source)
    # A 3 s start is too short for the correct controllers at speed: collisions, but none
    # that braking could have avoided; the rows differ by street (the child's walk).
    short = {(r.source.split(",")[0], r.controller): r for r in results[1].rows}
    assert short["8th Street", "reference"].violations
    text = format_sensitivity(results)
    assert text.startswith("default: 6 s start, 9 m/s^2 peak, 0.2 s brake delay")
    assert "reference: 0-0 avoidable violations per setting, clean in 3 of 3" in text
    assert "3.6 m lane mutant: " in text and "clean in 0 of 3" in text
    with pytest.raises(InvalidArgument, match="settings"):
        sensitivity_campaign(shared_data, settings=[])


@pytest.mark.slow  # 23 s; the campaign itself is tested above, this is its command line
def test_the_command_line_takes_the_car_and_runs_the_sensitivity(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["--data", str(shared_data), "--min-speed", "24", "--max-speed", "25", "--no-artifacts"]
    assert main([*argv, "--start", "4", "--deceleration", "8", "--brake-delay", "0.1"]) == 0
    out = capsys.readouterr().out
    assert "start 4 s, 8 m/s^2 peak, 0.1 s brake delay, 0.1 s sensor latency" in out
    assert main([*argv, "--sensitivity"]) == 0
    out = capsys.readouterr().out
    assert "sensitivity" in out and "latency 0.2 s" in out and "Range over the settings" in out
    with pytest.raises(SystemExit, match="max_deceleration"):
        main([*argv, "--deceleration", "0"])
