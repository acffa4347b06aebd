"""Option values out of range are usage errors naming the option (issue 25 item 10)."""

from __future__ import annotations

import pytest

from ami_xr.app.cli import EXIT_USAGE, main


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["identify", "x.nc", "--max-modes", "99999999999999999999"], "--max-modes"),
        (["identify", "x.nc", "--max-modes", "0"], "--max-modes"),
        (["identify", "x.nc", "--delta", "1.5"], "--delta"),
        (["identify", "x.nc", "--pfa", "nan"], "--pfa"),
        (["identify", "x.nc", "--band", "-1"], "--band"),
        (["frf", "t.nc", "-o", "g.nc", "--overload-samples", "-1"], "--overload-samples"),
        (["frf", "t.nc", "-o", "g.nc", "--double-impact-threshold", "-1"], "--double-impact"),
        (["frf", "t.nc", "-o", "g.nc", "--weak-force-ratio", "nan"], "--weak-force-ratio"),
        (["frf", "t.nc", "-o", "g.nc", "--n-average", "0"], "--n-average"),
        (["frf", "t.nc", "-o", "g.nc", "--exponential-decay", "1e308"], "--exponential-decay"),
        (["batch", "d", "-o", "o", "--workers", "0"], "--workers"),
        (["simulate", "random", "-o", "s.nc", "--noise", "-0.1"], "--noise"),
        (["simulate", "random", "-o", "s.nc", "--points", "1000"], "--points"),
    ],
)
def test_out_of_range_option_is_a_usage_error_naming_the_option(argv, option, capsys):
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == EXIT_USAGE
    err = capsys.readouterr().err
    assert f"argument {option}" in err and "expected" in err
    assert "np.float64" not in err and "Traceback" not in err


def test_in_range_values_still_parse():
    from ami_xr.app.cli import build_parser

    args = build_parser().parse_args(
        [
            "frf",
            "t.nc",
            "-o",
            "g.nc",
            "--overload-samples",
            "3",
            "--weak-force-ratio",
            "0.2",
            "--n-average",
            "4",
            "--exponential-decay",
            "12.5",
            "--double-impact-threshold",
            "0.1",
        ]
    )
    assert (args.overload_samples, args.weak_force_ratio, args.n_average) == (3, 0.2, 4)
    assert (args.exponential_decay, args.double_impact_threshold) == (12.5, 0.1)
    args = build_parser().parse_args(["identify", "x.nc", "--band", "all", "--max-modes", "40"])
    assert args.band == "all" and args.max_modes == 40
