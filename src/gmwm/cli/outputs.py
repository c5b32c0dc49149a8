"""Files the ``gmwm`` commands write besides their output on stdout: CSV tables and figures, each
written atomically (:mod:`gmwm.atomic`)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from gmwm.formatting import csv_text


def write_table(path: str, headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> None:
    """The table as CSV (``-o``; the name's suffix was checked by the parser)."""
    from gmwm.atomic import write_text_atomic

    write_text_atomic(path, csv_text(headers, rows))


def save_plot(ax_or_fig: Any, path: str) -> None:
    """Save the figure of an Axes (or a Figure) to ``path``."""
    from gmwm.atomic import save_figure

    save_figure(getattr(ax_or_fig, "figure", ax_or_fig), path)


def plot_channels(items: Mapping[str, Any], draw: Callable[[Any, Any, str], Any], path: str
                  ) -> None:
    """One panel per channel (``draw(obj, ax, name)``), titled by the channel when there are
    several, saved to ``path``."""
    from gmwm.plots import channel_grid

    fig, axes = channel_grid(len(items))
    for ax, (name, obj) in zip(axes, items.items(), strict=False):
        draw(obj, ax, name)
        if len(items) > 1:
            ax.set_title(name)
    save_plot(fig, path)
