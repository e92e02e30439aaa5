"""The progress display leaves nothing behind when a command fails mid-stage."""

import io

from pgc.progress import ProgressPrinter


def test_bars_of_unfinished_stages_are_closed_so_later_bars_never_touch_a_closed_stream():
    gone = io.StringIO()
    printer = ProgressPrinter(gone)
    printer.pgc_stage_started("fit_splats", {"total": 10})  # the command fails here: no stage_finished
    ProgressPrinter.close_all()
    gone.close()
    later = io.StringIO()
    second = ProgressPrinter(later)
    second.pgc_stage_started("mesh", {"total": 2})           # tqdm would redraw the first bar on `gone`
    second.pgc_stage_progress("mesh", 1, 2, {"loss": 0.5})
    second.pgc_stage_finished("mesh", 0.1, {})
    assert "[mesh]" in later.getvalue()
