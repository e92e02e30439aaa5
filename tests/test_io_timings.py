"""Wall-clock figures are kept apart from results (pgc.io.timings)."""

from pgc.io.timings import read_timings, split_timings, write_timings


def test_split_timings_separates_every_wall_clock_figure_at_any_depth():
    figures = {"mesh": {"seconds_hull": 1.0, "vertices": 10}, "fit": {"fit_seconds": 2.0, "psnr": 30.0,
               "curve": [{"iteration": 10, "seconds": 0.5, "psnr": 20.0}, {"iteration": 20, "psnr": 21.0}]},
               "seconds": {"mesh": 3.0}, "secondsish": 4}
    kept, timed = split_timings(figures)
    assert kept == {"mesh": {"vertices": 10}, "fit": {"psnr": 30.0, "curve": [{"iteration": 10, "psnr": 20.0},
                                                                              {"iteration": 20, "psnr": 21.0}]},
                    "secondsish": 4}
    assert timed == {"mesh": {"seconds_hull": 1.0}, "fit": {"fit_seconds": 2.0, "curve": [{"seconds": 0.5}, None]},
                     "seconds": {"mesh": 3.0}}
    assert split_timings({"a": 1}) == ({"a": 1}, None) and split_timings(5) == (5, None)


def test_timings_round_trip_and_missing_or_broken_files_read_as_empty(tmp_path):
    write_timings(tmp_path, {"seconds": {"mesh": 1.5}})
    assert read_timings(tmp_path) == {"seconds": {"mesh": 1.5}}
    assert read_timings(tmp_path / "nowhere") == {}
    (tmp_path / "timings.json").write_text("{")
    assert read_timings(tmp_path) == {}
