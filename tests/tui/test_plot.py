"""The monitor's plot (no Textual): columns binned by time with their min and max, zoom and pan, rendering."""

from __future__ import annotations


from rs30x_sniff.tui.plot import Window, columns, render


def test_each_column_holds_the_min_and_max_of_its_time_slice():
    times = [i / 100 for i in range(1000)]            # 10 s at 100 Hz
    values = [float(i % 10) for i in range(1000)]      # a saw tooth 0..9 every 0.1 s
    cols = columns(times, values, 0.0, times[-1], 50)  # 0.2 s a column: a whole tooth in each
    assert len(cols) == 50 and all(c == (0.0, 9.0) for c in cols)
    sparse = columns([1.0, 9.5], [5.0, 7.0], 0.0, 11.0, 11)
    assert sparse[1] == (5.0, 5.0) and sparse[9] == (7.0, 7.0) and sparse[5] is None


def test_zoom_and_pan_stay_inside_the_data():
    w = Window()
    assert w.bounds(0.0, 600.0) == (0.0, 600.0)
    w.zoom(0.5, 0.0, 600.0)
    assert w.bounds(0.0, 600.0) == (300.0, 600.0)  # the newest half
    w.pan(-0.25, 0.0, 600.0)
    assert w.bounds(0.0, 600.0) == (225.0, 525.0)
    for _ in range(10):
        w.pan(-1.0, 0.0, 600.0)
    assert w.bounds(0.0, 600.0) == (0.0, 300.0)  # no further back than the first sample
    w.zoom(4.0, 0.0, 600.0)
    assert w.span is None and w.bounds(0.0, 600.0) == (0.0, 600.0)  # wider than the data: all of it


def test_render_draws_every_series_in_the_window():
    a = ([0.0, 1.0, 2.0], [0.0, 10.0, 0.0])
    b = ([0.0, 2.0], [5.0, 5.0])
    rows, vmin, vmax = render([a, b], 10, 5, 0.0, 2.0)
    assert (vmin, vmax) == (0.0, 10.0) and len(rows) == 5
    text = [r.plain for r in rows]
    assert all(len(line) == 10 for line in text)
    assert text[0].count("▬") == 1 and text[-1][0] == "▬" and text[-1][-1] == "▬"  # a's peak and ends
    assert text[2][0] == "▬"  # b at 5.0, half way
    assert render([], 10, 3, 0.0, 1.0)[1] is None
