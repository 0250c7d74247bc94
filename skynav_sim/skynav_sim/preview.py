# SPDX-License-Identifier: Apache-2.0
"""Contact sheets: what a synthetic recording shows (UV, green, ground-truth mask; or a colour camera's frame, its
blue channel and the mask) and where (a top view)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from skynav_core.rotations import as_matrix

from .world import YARD_RADIUS, World

KIND_COLOURS = {
    'tree': '#2e7d32',
    'bush': '#66bb6a',
    'building': '#8d6e63',
    'wall': '#9e9e9e',
    'fence': '#a1887f',
    'hedge': '#1b5e20',
    'rock': '#bdbdbd',
}
TOP_VIEW_MARGIN = 14.0  # m shown around the yard


@dataclass
class SheetFrame:
    """One frame of the sheet: the images as captured and where the camera was."""

    index: int
    uv: np.ndarray  # a colour camera: its blue channel (linear), which stands in for UV
    green: np.ndarray
    mask: np.ndarray  # 255 sky / 0 ground
    position: np.ndarray  # (3,) camera_link in map (m)
    quaternion: np.ndarray  # (4,) x, y, z, w
    caption: str
    colour: np.ndarray | None = None  # a colour camera's frame: (H, W, 3) uint8 sRGB, shown as it is


def _display(image: np.ndarray) -> np.ndarray:
    """Return an image scaled to [0, 1] for display with a gamma that shows dark and bright parts."""
    values = image.astype(np.float64)
    top = np.percentile(values, 99.9) if values.dtype.kind == 'f' or values.max() > 0 else 1.0
    return np.clip(values / max(top, 1e-12), 0, 1) ** 0.5


def draw_world(figure, axis, world: World, extent: float) -> None:
    """Draw a top view of a world into `axis`: relief, object footprints (crowns shaded), the yard's edge."""
    from matplotlib.patches import Circle, Rectangle

    axis_values = np.linspace(-extent, extent, 300)
    x, y = np.meshgrid(axis_values, axis_values)
    relief = axis.imshow(
        world.terrain.height(x, y), origin='lower', extent=(-extent, extent, -extent, extent), cmap='terrain', alpha=0.8
    )
    figure.colorbar(relief, ax=axis, shrink=0.5, label='terrain height (m)')
    for f in world.footprints:
        colour = KIND_COLOURS.get(f.kind, 'k')
        if f.canopy:
            axis.add_patch(Circle(tuple(f.center), f.canopy, color=colour, alpha=0.35))
        if f.disc:
            axis.add_patch(Circle(tuple(f.center), f.half_sizes[0], color=colour))
        else:
            corner = f.center - Rotation.from_euler('z', f.yaw).apply([*f.half_sizes, 0])[:2]
            axis.add_patch(
                Rectangle(corner, 2 * f.half_sizes[0], 2 * f.half_sizes[1], angle=np.degrees(f.yaw), color=colour)
            )
    axis.add_patch(Circle((0, 0), YARD_RADIUS, fill=False, linestyle='--', color='k', linewidth=0.8))
    axis.set_xlim(-extent, extent)
    axis.set_ylim(-extent, extent)
    axis.set_aspect('equal')
    axis.set_xlabel('x east (m)')
    axis.set_ylabel('y north (m)')


def draw(
    path: str | Path, frames: list[SheetFrame], all_positions: np.ndarray, world: World | None, title: str
) -> Path:
    """Draw the contact sheet of `frames` (and a top view of `world` with every pose) into a PNG file."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    rows = len(frames)
    figure = plt.figure(figsize=(4 * 3 + 7, max(3.2 * rows, 7)), layout='constrained')
    grid = figure.add_gridspec(max(rows, 1), 4, width_ratios=[1.75, 1, 1, 1])
    top = figure.add_subplot(grid[:, 0])
    extent = YARD_RADIUS + TOP_VIEW_MARGIN
    if world is not None:
        draw_world(figure, top, world, extent)
    top.plot(all_positions[:, 0], all_positions[:, 1], '.', color='#1565c0', markersize=3, label='all poses')
    for frame in frames:
        forward = as_matrix(frame.quaternion)[:, 0]  # camera_link x (the robot's forward) in map
        top.annotate(
            '',
            tuple(frame.position[:2] + 0.8 * forward[:2]),
            tuple(frame.position[:2]),
            arrowprops={'arrowstyle': '->', 'color': '#d32f2f', 'linewidth': 1.5},
        )
        label_x, label_y = frame.position[:2] + [0.3, 0.3]
        top.text(label_x, label_y, str(frame.index), color='#d32f2f', fontsize=9)
    top.set_xlim(-extent, extent)
    top.set_ylim(-extent, extent)
    top.set_aspect('equal')
    ground = (
        'synthetic world'
        if world is None or world.backdrop is None
        else f'synthetic lawn, real {world.style} skyline {world.backdrop.distance:g} m away'
    )
    top.set_title(f'top view ({ground}); red: frames shown, arrow = robot forward')
    for row, frame in enumerate(frames):
        panels = (
            ((frame.uv, 'UV'), (frame.green, 'green'), (frame.mask, 'ground-truth mask'))
            if frame.colour is None
            else ((frame.colour, 'colour (sRGB)'), (frame.uv, 'blue (linear)'), (frame.mask, 'ground-truth mask'))
        )
        for column, (image, name) in enumerate(panels):
            ax = figure.add_subplot(grid[row, column + 1])
            if image.ndim == 3:
                ax.imshow(image)
            else:
                ax.imshow(_display(image), cmap='gray', vmin=0, vmax=1)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(
                f'frame {frame.index}: {name}' if column else f'frame {frame.index}: {name}\n{frame.caption}',
                fontsize=9,
            )
    figure.suptitle(title)
    path = Path(path)
    figure.savefig(path, dpi=70)
    plt.close(figure)
    return path
