"""Rendering of one MATE world with pygame: the frames behind `env.render()`.

A `Renderer` draws the world of a `MultiAgentTracking` env (read through its public API:
`env.get_world()` and `env.params`) onto an offscreen 800 x 800 canvas. World coordinates
[-1050, 1050] on both axes fill the canvas (x to the right, y up); lengths are world units,
angles degrees, colours RGB floats in [0, 1] (docs/rendering.md).

Drawing order:
    persistent layer (cached until obstacles or warehouse states change):
        terrain border, warehouses (square + vector icon), obstacles
    per-frame layer:
        primitives queued with layer='below' (e.g. communication arrows),
        per camera: full field-of-view sector (cyan), visible region clipped by occlusion
        (green if the camera tracks a target, olive otherwise),
        camera bodies, yellow discs under tracked targets, targets,
        primitives queued with layer='above' (the default),
        the heads-up line (HUD, unless `renderer.hud` is False): a translucent band across the top
        rows (`renderer.hud_height` pixels) with the env's name, episode step, coverage rate and
        delivered / total cargo.

Small canvases: targets are drawn at least `MIN_TARGET_PIXELS` long and camera bodies at least
`MIN_CAMERA_PIXELS` in radius, so that frames below the default size stay readable (at the
default 800 pixels both minimums are below the true sizes and change nothing).

'human' mode needs a display. On Linux and other X11/Wayland systems, when SDL_VIDEODRIVER is
not set, the window is opened with the driver the environment points to (x11 if DISPLAY is set,
wayland if WAYLAND_DISPLAY is); without either, or when SDL cannot open the window, rendering
raises a one-line RuntimeError suggesting render_mode='rgb_array' (or SDL_VIDEODRIVER=dummy for
an invisible window), instead of silently drawing into SDL's offscreen driver.

Render callbacks registered with `env.add_render_callback(name, callback)` are called as
`callback(env, renderer)` at every render; they draw with the renderer's primitives
(`line`, `dashed_line`, `arrow`, `dashed_arrow`, `polygon`, `circle`), which take world
coordinates and are drawn in the frame being rendered.

pygame is imported only when a `Renderer` is created, never by `import mate`.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import tempfile
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from ..constants import NUM_WAREHOUSES, TARGET_STATE_DIM_PRIVATE, TERRAIN_SIZE, WAREHOUSE_RADIUS, WAREHOUSES

__all__ = [
    'MIN_CAMERA_PIXELS', 'MIN_TARGET_PIXELS', 'TARGET_RENDER_SIZE', 'WAREHOUSE_COLORS', 'WINDOW_SIZE',
    'WORLD_BOUND', 'Renderer', 'hud_line', 'sector_polygon', 'visible_region',
]

WINDOW_SIZE = 800
"""Default canvas side in pixels."""
WORLD_BOUND = 1050.0
"""The canvas shows world coordinates [-1050, 1050] on both axes (5% margin around the terrain)."""
TARGET_RENDER_SIZE = 27.5
"""Scale of the target shapes (world units); a target is 1.8 x this long, nose to tail."""
MIN_TARGET_PIXELS = 16.0
"""Smallest drawn target length, nose to tail (pixels); applies below ~680-pixel canvases."""
MIN_CAMERA_PIXELS = 7.0
"""Smallest drawn camera body radius (pixels)."""
ANGLE_STEP = 0.5
"""Angular spacing of the rays sampling sectors and occlusion profiles (degrees)."""

WAREHOUSE_COLORS = np.array([[52, 127, 212], [255, 34, 34], [149, 117, 205], [134, 110, 68]]) / 255.0
"""(4, 3) RGB in [0, 1] per warehouse: blue (NE), red (NW), purple (SW), brown (SE)."""

WHITE = (1.0, 1.0, 1.0)
OBSTACLE_COLOR = (0.3, 0.3, 0.3)
SECTOR_COLOR, SECTOR_ALPHA = (0.0, 0.6, 0.8), 0.1
TRACKING_COLOR, IDLE_COLOR, VISIBLE_ALPHA = (0.0, 0.6, 0.0), (0.6, 0.6, 0.0), 0.25
CAMERA_COLOR, SPOTTED_CAMERA_COLOR = (0.1, 0.2, 0.6), (0.6, 0.2, 0.1)
LENS_COLOR = (0.1, 0.1, 0.1)
TRACKED_MARKER_COLOR = (1.0, 1.0, 0.0)
UNLOADED_TARGET_COLOR = (0.2, 0.6, 0.2)
ICON_COLOR = (0.15, 0.15, 0.15)
HUD_TEXT_COLOR, HUD_BACKGROUND_ALPHA = ICON_COLOR, 0.8
HUD_MIN_FONT_SIZE = 10
"""HUD font size (pixels) on canvases below 660 pixels; it grows as window_size // 60 above."""
HUD_PADDING = 2
"""Pixels of band above and below the HUD text (twice that left of it)."""

# Target outlines in units of the target size (TARGET_RENDER_SIZE or more), heading along +x.
TARGET_SHAPES = {
    1: np.array([[1.0, 0.0], [-0.2, 0.6], [-0.8, 0.6], [-0.4, 0.0], [-0.8, -0.6], [-0.2, -0.6]]),
    2: np.array([[1.0, 0.0], [0.3, 0.6], [-0.8, 0.6], [-0.8, -0.6], [0.3, -0.6]]),
}

LAYERS = ('below', 'above')


def _pygame():
    """Import pygame (and its gfxdraw module) on first use, with a helpful error if missing."""
    os.environ.setdefault('PYGAME_HIDE_SUPPORT_PROMPT', '1')
    try:
        import pygame
        import pygame.gfxdraw
        import pygame.freetype
    except ImportError as exc:
        raise ImportError("rendering needs pygame: pip install 'mate[render]' (or pip install pygame)") from exc
    return pygame


def hud_line(world: dict, name: str | None = None, max_episode_steps: int | None = None) -> str:
    """The heads-up line of a world dict (as from `env.get_world()`), e.g.
    'MultiAgentTracking(4v8, 9) | step 120/2000 | coverage 0.62 | delivered 12/64'.

    coverage: share of targets seen by some camera at this step; delivered: cargo units delivered
    so far / all units (delivered + waiting in warehouses + carried by targets).
    """
    step = int(world['episode_step'])
    delivered = int(world['num_delivered_cargoes'])
    goal_bits = slice(6, 6 + NUM_WAREHOUSES)   # units carried per destination (a target's private state)
    states = np.asarray(world['target_state'], dtype=np.float64).reshape(-1, TARGET_STATE_DIM_PRIVATE)
    carried = states[:, goal_bits].sum()
    total = delivered + int(np.sum(world['remaining_cargoes'])) + int(round(carried))
    parts = [] if name is None else [str(name)]
    parts.append(f'step {step}' if max_episode_steps is None else f'step {step}/{int(max_episode_steps)}')
    parts.append(f"coverage {float(world['coverage_rate']):.2f}")
    parts.append(f'delivered {delivered}/{total}')
    return ' | '.join(parts)


def _rotation(degrees: float) -> np.ndarray:
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return np.array([[c, s], [-s, c]])  # right-multiplies row vectors: p @ R rotates p by `degrees`


# --------------------------------------------------------------------------- geometry (world units)

def _sector_offsets(viewing_angle: float, step: float = ANGLE_STEP) -> np.ndarray:
    half = 0.5 * viewing_angle
    n = max(2, math.ceil(viewing_angle / step) + 1)
    return np.linspace(-half, half, n)


def sector_polygon(center, orientation: float, viewing_angle: float, radius: float,
                   step: float = ANGLE_STEP) -> np.ndarray:
    """(K + 1, 2) polygon of a circular sector: the apex, then arc points every `step` degrees
    from `orientation - viewing_angle / 2` to `orientation + viewing_angle / 2`."""
    angles = np.radians(orientation + _sector_offsets(viewing_angle, step))
    arc = np.asarray(center, dtype=np.float64) + radius * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    return np.vstack([center, arc])


def visible_region(center, orientation: float, viewing_angle: float, sight_range: float, camera_radius: float,
                   discs, max_sight_range: float | None = None, step: float = ANGLE_STEP,
                   arc_step: float | None = None) -> np.ndarray:
    """(K + 1, 2) polygon of the part of a camera's sector that no disc hides.

    `discs` (M, 3) `[x, y, r]` are the occluding obstacles. Rays are cast across the sector
    every `arc_step` degrees (default `step`), every `step` degrees where a disc lies, and just
    inside and outside each disc's tangent directions; each ray stops at its exact entry into
    the first disc (length 0 if the camera is inside a disc), is capped at `max_sight_range`,
    and its length is clamped to `[camera_radius, sight_range]`. The polygon is the camera
    centre followed by the ray ends in increasing angle.
    """
    center = np.asarray(center, dtype=np.float64)
    discs = np.asarray(discs, dtype=np.float64).reshape(-1, 3)
    discs = discs[discs[:, 2] > 0.0]
    half = 0.5 * viewing_angle
    pieces = [_sector_offsets(viewing_angle, step if arc_step is None else arc_step)]
    rel = discs[:, :2] - center
    dist = np.hypot(rel[:, 0], rel[:, 1])
    radius = discs[:, 2]
    outside = dist > radius
    eps = 1e-3
    for (dx, dy), d, r in zip(rel[outside], dist[outside], radius[outside]):
        half_width = math.degrees(math.asin(r / d))
        bearing = math.degrees(math.atan2(dy, dx)) - orientation
        count = math.ceil(2.0 * half_width / step) + 1
        pieces.append(bearing + np.linspace(-half_width + eps, half_width - eps, count))
        pieces.append(bearing + np.array([-half_width - eps, half_width + eps]))
    offsets = pieces[0]  # the sector's own rays, edges included exactly
    if len(pieces) > 1:
        extra = (np.concatenate(pieces[1:]) + 180.0) % 360.0 - 180.0
        offsets = np.unique(np.concatenate([offsets, extra[np.abs(extra) < half]]))
    angles = np.radians(orientation + offsets)
    direction = np.stack([np.cos(angles), np.sin(angles)], axis=1)           # (K, 2)
    lengths = np.full(len(offsets), np.inf if max_sight_range is None else float(max_sight_range))
    if len(discs):
        along = direction @ rel.T                                            # (K, M)
        off_sq = dist ** 2 - along ** 2
        hit = (off_sq < radius ** 2) & (along > 0.0)
        entry = np.where(hit, along - np.sqrt(np.maximum(radius ** 2 - off_sq, 0.0)), np.inf)
        entry = np.where(outside, entry, 0.0)                                # camera inside a disc: blind
        lengths = np.minimum(lengths, entry.min(axis=1))
    lengths = np.clip(lengths, camera_radius, sight_range)
    return np.vstack([center, center + lengths[:, None] * direction])


# --------------------------------------------------------------------------- warehouse icons

def _icon_shapes(sending: bool, receiving: bool) -> list[tuple[np.ndarray, tuple, float]]:
    """Vector icon in units of the icon size (coordinates in [-0.5, 0.5]): a small building,
    plus an outgoing arrow (cargo to send) on its right and an incoming arrow (awaiting cargo)
    on its left. Returns (polygon, colour, alpha) items; `None` colour = the warehouse colour."""
    shapes = [
        (np.array([[-0.22, -0.30], [0.22, -0.30], [0.22, 0.04], [-0.22, 0.04]]), WHITE, 0.9),   # walls
        (np.array([[-0.30, 0.04], [0.30, 0.04], [0.0, 0.30]]), ICON_COLOR, 0.85),             # roof
        (np.array([[-0.08, -0.30], [0.08, -0.30], [0.08, -0.08], [-0.08, -0.08]]), None, 1.0),  # door
    ]
    if not (sending or receiving):  # idle: shutters across the door
        shapes.append((np.array([[-0.08, -0.20], [0.08, -0.20], [0.08, -0.17], [-0.08, -0.17]]), ICON_COLOR, 0.85))
    arrow = np.array([[0.0, -0.035], [0.10, -0.035], [0.10, -0.09], [0.20, 0.0],
                      [0.10, 0.09], [0.10, 0.035], [0.0, 0.035]])
    if sending:
        shapes.append((arrow + [0.26, -0.12], ICON_COLOR, 0.9))
    if receiving:
        shapes.append((arrow + [-0.47, -0.12], ICON_COLOR, 0.9))
    return shapes


# --------------------------------------------------------------------------- renderer

class Renderer:
    """Draws MATE worlds with pygame; one per environment (`env.viewer`).

    mode: 'rgb_array' (frames returned as (H, W, 3) uint8 arrays, top row first) or 'human'
    (a pygame window, refreshed at most `fps` times per second; None = unthrottled).
    hud: draw the heads-up line (`hud_line`) across the top of every frame; the attribute
    `renderer.hud` can be switched at any time (`env.render_hud` sets it for `env.render()`).
    """

    def __init__(self, mode: str = 'rgb_array', window_size: int = WINDOW_SIZE, fps: float | None = None,
                 caption: str = 'MATE: Multi-Agent Tracking Environment', hud: bool = True) -> None:
        if mode not in ('human', 'rgb_array'):
            raise ValueError(f"Renderer mode must be 'human' or 'rgb_array', got {mode!r}")
        window_size = int(window_size)
        if window_size < 16:
            raise ValueError(f'window_size must be at least 16 pixels, got {window_size}')
        self._pg = _pygame()
        self.mode = mode
        self.window_size = window_size
        self.fps = fps
        self.caption = caption
        self.hud = bool(hud)
        self.scale = window_size / (2.0 * WORLD_BOUND)
        # scale of the drawn target shapes (world units): TARGET_RENDER_SIZE, or more on small canvases
        self.target_size = max(TARGET_RENDER_SIZE, MIN_TARGET_PIXELS / (1.8 * self.scale))
        self._font = None
        self.canvas = self._surface()
        self.window = None
        self.clock = None
        self.world: dict | None = None   # the world being rendered (valid inside callbacks)
        self.env = None
        self._queue: dict[str, list] = {layer: [] for layer in LAYERS}
        self._background = None
        self._background_key = None

    def __reduce__(self):
        # pickling / deep-copying gives a fresh renderer (no window, empty queues, no cache)
        return (type(self), (self.mode, self.window_size, self.fps, self.caption, self.hud))

    # ------------------------------------------------------------------ coordinates
    def to_pixels(self, points) -> np.ndarray:
        """World (x, y) -> canvas pixel (column, row) as floats; any leading shape."""
        p = np.asarray(points, dtype=np.float64)
        out = np.empty_like(p)
        out[..., 0] = (p[..., 0] + WORLD_BOUND) * self.scale
        out[..., 1] = (WORLD_BOUND - p[..., 1]) * self.scale
        return out

    def to_world(self, pixels) -> np.ndarray:
        """Canvas pixel (column, row) -> world (x, y); use pixel + 0.5 for a pixel centre."""
        p = np.asarray(pixels, dtype=np.float64)
        out = np.empty_like(p)
        out[..., 0] = p[..., 0] / self.scale - WORLD_BOUND
        out[..., 1] = WORLD_BOUND - p[..., 1] / self.scale
        return out

    # ------------------------------------------------------------------ public entry points
    def render(self, env, onetime_callbacks: Iterable[Callable] = (),
               max_episode_steps: int | None = None) -> np.ndarray | None:
        """Draw `env`'s current world; run its render callbacks and `onetime_callbacks` (each
        `callback(env, renderer)`). Returns the frame in 'rgb_array' mode, None in 'human'.
        max_episode_steps: the step limit shown in the HUD (default `env.max_episode_steps`)."""
        self.env = env
        self.world = world = env.get_world()
        callbacks = list(getattr(env, 'render_callbacks', {}).values()) + list(onetime_callbacks)
        try:
            for callback in callbacks:
                callback(env, self)
            self.draw(world, transmittance=float(env.params.transmittance), name=env.name,
                      max_episode_steps=env.max_episode_steps if max_episode_steps is None else max_episode_steps)
        except BaseException:
            self._queue = {layer: [] for layer in LAYERS}  # a failed frame leaves nothing behind
            raise
        finally:
            self.env = None
            self.world = None
        return self._present()

    def frame(self, world: dict, transmittance: float = 0.0, name: str | None = None,
              max_episode_steps: int | None = None) -> np.ndarray:
        """Draw a world dict (as from `env.get_world()`) and return the (H, W, 3) uint8 frame;
        `name` and `max_episode_steps` go into the HUD (see `hud_line`)."""
        self.draw(world, transmittance, name, max_episode_steps)
        return self.array()

    def _surface(self):
        """A 24-bit surface whose bytes are R, G, B in memory (so frames are a plain copy)."""
        masks = (0xFF, 0xFF00, 0xFF0000, 0) if sys.byteorder == 'little' else (0xFF0000, 0xFF00, 0xFF, 0)
        return self._pg.Surface((self.window_size, self.window_size), 0, 24, masks=masks)

    def array(self) -> np.ndarray:
        """The canvas as a fresh (H, W, 3) uint8 array, top row first."""
        size = self.window_size
        buffer = self.canvas.get_buffer()
        try:
            rows = np.frombuffer(buffer, dtype=np.uint8).reshape(size, self.canvas.get_pitch())
            return rows[:, :3 * size].reshape(size, size, 3).copy()
        finally:
            del buffer

    def close(self) -> None:
        """Close the window (if any). The renderer can still draw offscreen afterwards."""
        if self.window is not None:
            self._pg.display.quit()
            self.window = None
            self.clock = None

    @property
    def is_open(self) -> bool:
        """Whether the 'human' window is open."""
        return self.window is not None

    # ------------------------------------------------------------------ primitives (queued, world units)
    # Each call queues a shape for the next frame drawn (the current one when called from a render
    # callback): layer 'below' = under the cameras' sectors and bodies and the targets (where the
    # communication arrows go), 'above' = on top of everything.
    def _enqueue(self, layer: str, command: Callable[[], None]) -> None:
        if layer not in LAYERS:
            raise ValueError(f'layer must be one of {LAYERS}, got {layer!r}')
        self._queue[layer].append(command)

    def line(self, start, end, color, alpha: float = 1.0, width: float = 1.0, layer: str = 'above') -> None:
        """A straight segment between two world points; `width` in pixels."""
        rgba, seg = self._rgba(color, alpha), self.to_pixels([start, end])
        self._enqueue(layer, lambda: self._thick_segments(seg[None], rgba, width))

    def dashed_line(self, start, end, color, alpha: float = 1.0, width: float = 2.5, dash: float = 4.0,
                    gap: float = 4.0, layer: str = 'above') -> None:
        """A dashed segment: `dash` pixels drawn, `gap` pixels skipped (default = stipple 0x0F0F)."""
        rgba, seg = self._rgba(color, alpha), self.to_pixels([start, end])
        dashes = self._dashes(seg, dash, gap)
        self._enqueue(layer, lambda: self._thick_segments(dashes, rgba, width))

    def arrow(self, start, end, color, alpha: float = 1.0, width: float = 2.5, head_length: float | None = None,
              head_angle: float = 20.5, barbs: str = 'both', dashed: bool = False, dash: float = 4.0,
              gap: float = 4.0, layer: str = 'above') -> None:
        """An arrow from `start` to `end` with barbs at `end`.

        head_length: barb length in world units (default 4.3% of the arrow length, at most 50);
        barbs: 'both', 'left' or 'right' (seen looking along the arrow) or 'none'.
        """
        if barbs not in ('both', 'left', 'right', 'none'):
            raise ValueError(f"barbs must be 'both', 'left', 'right' or 'none', got {barbs!r}")
        rgba = self._rgba(color, alpha)
        if dashed:
            self._dashes(np.zeros((2, 2)), dash, gap)  # validate now rather than at drawing time
        start, end = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
        vector = end - start
        length = float(np.hypot(*vector))
        pieces = [self.to_pixels([start, end])]
        if length > 0.0 and barbs != 'none':
            size = min(50.0, 0.0427 * length) if head_length is None else float(head_length)
            back = -vector / length * size
            sides = {'left': -head_angle, 'right': head_angle}
            for side in (('left', 'right') if barbs == 'both' else (barbs,)):
                tip = end + back @ _rotation(sides[side])
                pieces.append(self.to_pixels([end, tip]))
        shaft, heads = pieces[0], pieces[1:]

        def draw() -> None:
            segments = self._dashes(shaft, dash, gap) if dashed else shaft[None]
            if heads:
                segments = np.concatenate([segments, np.stack(heads)])
            self._thick_segments(segments, rgba, width)
        self._enqueue(layer, draw)

    def dashed_arrow(self, start, end, color, alpha: float = 1.0, width: float = 2.5, **kwargs: Any) -> None:
        """`arrow(..., dashed=True)`: the look of the communication lines."""
        self.arrow(start, end, color, alpha=alpha, width=width, dashed=True, **kwargs)

    def polygon(self, points, color, alpha: float = 1.0, filled: bool = True, width: float = 1.0,
                layer: str = 'above') -> None:
        """A polygon through world points (filled, or its outline `width` pixels wide)."""
        rgba, pix = self._rgba(color, alpha), self.to_pixels(points)
        if filled:
            self._enqueue(layer, lambda: self._fill(pix, rgba))
        else:
            segments = np.stack([pix, np.roll(pix, -1, axis=0)], axis=1)
            self._enqueue(layer, lambda: self._thick_segments(segments, rgba, width))

    def circle(self, center, radius: float, color, alpha: float = 1.0, filled: bool = True, width: float = 1.0,
               layer: str = 'above') -> None:
        """A circle (72-gon) of `radius` world units around a world point."""
        self.polygon(self._disc(center, radius), color, alpha=alpha, filled=filled, width=width, layer=layer)

    # ------------------------------------------------------------------ low-level drawing (pixels)
    @staticmethod
    def _rgba(color, alpha: float = 1.0) -> tuple[int, int, int, int]:
        c = np.asarray(color, dtype=np.float64).ravel()
        if c.size not in (3, 4) or not np.all((c >= 0.0) & (c <= 1.0)) or not 0.0 <= alpha <= 1.0:
            raise ValueError(f'color must be RGB or RGBA floats in [0, 1] and alpha in [0, 1]; '
                             f'got color={color!r}, alpha={alpha!r}')
        a = alpha * (c[3] if c.size == 4 else 1.0)
        return (*(round(255.0 * v) for v in c[:3]), round(255.0 * a))

    @staticmethod
    def _disc(center, radius: float, sides: int = 72) -> np.ndarray:
        angles = np.linspace(0.0, 2.0 * math.pi, sides, endpoint=False)
        return np.asarray(center, dtype=np.float64) + radius * np.stack([np.cos(angles), np.sin(angles)], axis=1)

    def _fill(self, pixels: np.ndarray, rgba, surface=None) -> None:
        if rgba[3] == 0 or len(pixels) < 3:
            return
        surface = self.canvas if surface is None else surface
        pts = (pixels - 0.5).round().tolist()  # gfxdraw fills pixels whose centres lie inside
        if rgba[3] == 255:
            self._pg.draw.polygon(surface, rgba[:3], pts)
        else:
            self._pg.gfxdraw.filled_polygon(surface, pts, rgba)

    @staticmethod
    def _dashes(segment: np.ndarray, dash: float, gap: float) -> np.ndarray:
        """Split a pixel segment (2, 2) into dashes (K, 2, 2)."""
        if dash <= 0 or gap < 0:
            raise ValueError(f'dash must be > 0 and gap >= 0 pixels, got dash={dash}, gap={gap}')
        p0, p1 = segment
        length = float(np.hypot(*(p1 - p0)))
        if length == 0.0:
            return segment[None]
        starts = np.arange(0.0, length, dash + gap)
        ends = np.minimum(starts + dash, length)
        trim = min(0.5, 0.25 * dash)  # lines include both end pixels: keep dashes `dash` pixels long
        starts, ends = starts + trim, np.maximum(ends - trim, starts + trim)
        unit = (p1 - p0) / length
        return np.stack([p0 + starts[:, None] * unit, p0 + ends[:, None] * unit], axis=1)

    def _thick_segments(self, segments: np.ndarray, rgba, width: float) -> None:
        """Draw pixel segments (K, 2, 2) as lines `width` pixels wide, alpha-blended onto the canvas
        (all K are composed first, so overlaps are not blended twice)."""
        if rgba[3] == 0 or not len(segments):
            return
        pg = self._pg
        ends = np.round(segments - 0.5)  # pixel (i, j) has its centre at (i + 0.5, j + 0.5)
        thickness = max(1, int(width + 0.5))
        if rgba[3] == 255:
            for (x0, y0), (x1, y1) in ends.astype(int).tolist():
                pg.draw.line(self.canvas, rgba[:3], (x0, y0), (x1, y1), thickness)
            return
        size = self.window_size
        low = np.clip(np.floor(ends.min(axis=(0, 1))) - thickness, 0, size).astype(int)
        high = np.clip(np.ceil(ends.max(axis=(0, 1))) + thickness + 1, 0, size).astype(int)
        if np.any(high <= low):
            return
        layer = pg.Surface(tuple(high - low), pg.SRCALPHA, 32)
        for (x0, y0), (x1, y1) in (ends - low).astype(int).tolist():
            pg.draw.line(layer, rgba, (x0, y0), (x1, y1), thickness)
        self.canvas.blit(layer, tuple(low))

    # ------------------------------------------------------------------ scene
    def draw(self, world: dict, transmittance: float = 0.0, name: str | None = None,
             max_episode_steps: int | None = None) -> None:
        """Draw a world dict onto the canvas (queued primitives are drawn and cleared), then the
        HUD if `self.hud`: `hud_line(world, name, max_episode_steps)`, without the name if the
        line would not fit in the frame."""
        self.canvas.blit(self._persistent_layer(world), (0, 0))
        queue, self._queue = self._queue, {layer: [] for layer in LAYERS}
        for command in queue['below']:
            command()
        self._draw_cameras(world, transmittance)
        self._draw_targets(world)
        for command in queue['above']:
            command()
        if self.hud:
            self._draw_hud(world, name, max_episode_steps)

    # ------------------------------------------------------------------ heads-up line
    @property
    def font(self):
        """The HUD's `pygame.freetype` font: pygame's bundled default font (no system fonts needed),
        `max(HUD_MIN_FONT_SIZE, window_size // 60)` pixels, not antialiased, placed by its baseline."""
        if self._font is None:
            freetype = self._pg.freetype
            freetype.init()
            self._font = freetype.Font(None, max(HUD_MIN_FONT_SIZE, self.window_size // 60))
            self._font.origin = True
            self._font.antialiased = False  # crisp, and few colours: GIF palettes stay exact and small
        return self._font

    @property
    def hud_height(self) -> int:
        """Rows (pixels) of the HUD band at the top of the frame; 0 when the HUD is off."""
        return self.font.get_sized_height() + 2 * HUD_PADDING if self.hud else 0

    def _draw_hud(self, world: dict, name: str | None, max_episode_steps: int | None) -> None:
        """A translucent white band over the top `hud_height` rows, the HUD line left-aligned in it."""
        text = hud_line(world, name, max_episode_steps)
        if name is not None and self.font.get_rect(text).width > self.window_size - 2 * HUD_PADDING:
            text = hud_line(world, None, max_episode_steps)
        band = self._pg.Surface((self.window_size, self.hud_height), self._pg.SRCALPHA, 32)
        band.fill(self._rgba(WHITE, HUD_BACKGROUND_ALPHA))
        baseline = HUD_PADDING + self.font.get_sized_ascender()
        self.font.render_to(band, (2 * HUD_PADDING, baseline), text, self._rgba(HUD_TEXT_COLOR))
        self.canvas.blit(band, (0, 0))

    def _persistent_layer(self, world: dict):
        remaining = np.asarray(world['remaining_cargoes'])
        awaiting = np.asarray(world['awaiting_cargo_counts'])
        sending, receiving = remaining.sum(axis=1) > 0, awaiting > 0
        obstacles = np.asarray(world['obstacle_state'], dtype=np.float64).reshape(-1, 3)
        key = (sending.tobytes(), receiving.tobytes(), obstacles.tobytes())
        if key != self._background_key:
            self._background = self._draw_persistent(sending, receiving, obstacles)
            self._background_key = key
        return self._background

    def _draw_persistent(self, sending: np.ndarray, receiving: np.ndarray, obstacles: np.ndarray):
        surface = self._surface()
        surface.fill((255, 255, 255))
        # 1. terrain border, 3 px wide, centred on +-TERRAIN_SIZE
        lo, hi = self.to_pixels([[-TERRAIN_SIZE, TERRAIN_SIZE], [TERRAIN_SIZE, -TERRAIN_SIZE]])
        left, top = round(lo[0] - 1.5), round(lo[1] - 1.5)
        right, bottom = round(hi[0] + 1.5), round(hi[1] + 1.5)
        self._pg.draw.rect(surface, (0, 0, 0), (left, top, right - left, bottom - top), width=3)
        # 2. warehouses: translucent square + icon
        square = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]) * WAREHOUSE_RADIUS
        icon_size = 1.8 * WAREHOUSE_RADIUS
        for w, center in enumerate(WAREHOUSES):
            color = WAREHOUSE_COLORS[w]
            active = sending[w] or receiving[w]
            self._fill(self.to_pixels(center + square), self._rgba(color, 0.6 if active else 0.3), surface)
            for shape, shape_color, alpha in _icon_shapes(bool(sending[w]), bool(receiving[w])):
                rgba = self._rgba(color if shape_color is None else shape_color, alpha)
                self._fill(self.to_pixels(center + icon_size * shape), rgba, surface)
        # 3. obstacles
        rgba = self._rgba(OBSTACLE_COLOR)
        for x, y, r in obstacles:
            if r > 0.0:
                self._fill(self.to_pixels(self._disc((x, y), r)), rgba, surface)
        return surface

    def _draw_cameras(self, world: dict, transmittance: float) -> None:
        cameras = np.asarray(world['camera_state'], dtype=np.float64).reshape(-1, 9)
        if not len(cameras):
            return
        orientation = np.asarray(world['camera_orientation'], dtype=np.float64)
        viewing_angle = np.asarray(world['camera_viewing_angle'], dtype=np.float64)
        sight_range = np.asarray(world['camera_sight_range'], dtype=np.float64)
        obstacles = np.asarray(world['obstacle_state'], dtype=np.float64).reshape(-1, 3)
        obstacle_flags = np.asarray(world['camera_obstacle_view_mask'], dtype=bool).reshape(len(cameras), -1)
        tracking = np.asarray(world['camera_target_view_mask'], dtype=bool).reshape(len(cameras), -1).any(axis=1)
        spotted = np.asarray(world['target_camera_view_mask'], dtype=bool).reshape(-1, len(cameras)).any(axis=0)
        sector_rgba = self._rgba(SECTOR_COLOR, SECTOR_ALPHA)
        for c, (x, y, r_c) in enumerate(cameras[:, :3]):
            center = (x, y)
            arc_step = self._arc_step(sight_range[c])
            sector = sector_polygon(center, orientation[c], viewing_angle[c], sight_range[c], step=arc_step)
            self._fill(self.to_pixels(sector), sector_rgba)
            discs = obstacles[obstacle_flags[c]] if transmittance < 1.0 else obstacles[:0]
            region = visible_region(center, orientation[c], viewing_angle[c], sight_range[c], r_c, discs,
                                    max_sight_range=cameras[c, 6], arc_step=arc_step)
            color = TRACKING_COLOR if tracking[c] else IDLE_COLOR
            self._fill(self.to_pixels(region), self._rgba(color, VISIBLE_ALPHA))
        body_white, lens = self._rgba(WHITE, 0.75), self._rgba(LENS_COLOR, 0.75)
        for c, (x, y, r_c) in enumerate(cameras[:, :3]):
            center = np.array([x, y])
            r_c = max(r_c, MIN_CAMERA_PIXELS / self.scale)
            rotation = _rotation(orientation[c])
            body_color = SPOTTED_CAMERA_COLOR if spotted[c] else CAMERA_COLOR
            self._fill(self.to_pixels(self._disc(center, r_c)), self._rgba(body_color))
            plate = np.array([[-0.8, -0.6], [0.8, -0.6], [0.8, 0.6], [-0.8, 0.6]]) * r_c
            glass = np.array([[0.7, -0.3], [1.2, -0.3], [1.2, 0.3], [0.7, 0.3]]) * r_c
            self._fill(self.to_pixels(center + plate @ rotation), body_white)
            self._fill(self.to_pixels(center + glass @ rotation), lens)

    def _arc_step(self, radius: float, tolerance: float = 0.2) -> float:
        """Angular step (degrees, in [0.5, 5]) keeping chords of an arc within `tolerance` pixels."""
        pixels = max(radius * self.scale, 1.0)
        return float(np.clip(math.degrees(2.0 * math.acos(max(1.0 - tolerance / pixels, -1.0))), ANGLE_STEP, 5.0))

    def _draw_targets(self, world: dict) -> None:
        targets = np.asarray(world['target_state'], dtype=np.float64).reshape(-1, 14)
        if not len(targets):
            return
        tracked = np.asarray(world['camera_target_view_mask'], dtype=bool).reshape(-1, len(targets)).any(axis=0)
        goals = np.asarray(world['target_goal']).astype(int)
        bounty = np.asarray(world['target_bounty'])
        heading = np.asarray(world['target_heading'], dtype=np.float64)
        marker = self._rgba(TRACKED_MARKER_COLOR)
        for t in np.flatnonzero(tracked):
            self._fill(self.to_pixels(self._disc(targets[t, :2], 1.2 * self.target_size)), marker)
        badge = self._rgba(WHITE, 0.66)
        for t, state in enumerate(targets):
            center = state[:2]
            shape = TARGET_SHAPES[2 if state[5] >= 2 else 1] * self.target_size @ _rotation(heading[t])
            loaded = goals[t] >= 0
            color = WAREHOUSE_COLORS[goals[t]] if loaded else UNLOADED_TARGET_COLOR
            self._fill(self.to_pixels(center + shape), self._rgba(color))
            if loaded and bounty[t] <= 0:
                self._fill(self.to_pixels(center + 0.4 * shape), badge)

    # ------------------------------------------------------------------ output
    def _present(self) -> np.ndarray | None:
        if self.mode == 'rgb_array':
            return self.array()
        pg = self._pg
        if self.window is None:
            self._open_window()
        for event in pg.event.get():
            if event.type == pg.QUIT:
                self.close()
                return None
        self.window.blit(self.canvas, (0, 0))
        pg.display.flip()
        if self.fps:
            self.clock.tick(self.fps)
        return None

    def _open_window(self) -> None:
        """Open the 'human' window, or raise a one-line RuntimeError when no display can show it."""
        pg = self._pg
        driver = _display_driver()
        saved = os.environ.get('SDL_VIDEODRIVER')
        if driver is not None:
            os.environ['SDL_VIDEODRIVER'] = driver  # try only the display the environment names
        native_output: list[str] = []
        try:
            with _native_stderr(native_output):
                pg.display.init()
                if saved is None and pg.display.get_driver() in ('offscreen', 'dummy'):
                    raise pg.error(f'SDL fell back to its invisible {pg.display.get_driver()!r} driver')
                pg.display.set_caption(self.caption)
                self.window = pg.display.set_mode((self.window_size, self.window_size))
        except pg.error as exc:
            pg.display.quit()
            raise RuntimeError(f"render_mode='human' could not open a window ({exc}); {_HEADLESS_HINT}") from None
        finally:
            if driver is not None:
                os.environ.pop('SDL_VIDEODRIVER', None)
            # pass on what SDL printed, except libwayland's complaint about XDG_RUNTIME_DIR
            for line in native_output:
                if 'XDG_RUNTIME_DIR' not in line:
                    print(line, file=sys.stderr)
        self.clock = pg.time.Clock()


@contextlib.contextmanager
def _native_stderr(lines: list[str]):
    """Send what native code (SDL, libwayland) writes to file descriptor 2 meanwhile into `lines`
    instead (appended on exit); a no-op where descriptor 2 cannot be duplicated."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):
        yield
        return
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            lines.extend(sink.read().decode(errors='replace').splitlines())


_HEADLESS_HINT = ("use render_mode='rgb_array' (frames as arrays, e.g. for mate.tools.video.save_gif) "
                  'or set SDL_VIDEODRIVER=dummy to draw into an invisible window')


def _display_driver() -> str | None:
    """The SDL video driver to pin for a 'human' window: None when SDL_VIDEODRIVER is set or the
    platform has its own (Windows, macOS) or both DISPLAY and WAYLAND_DISPLAY are set; 'x11' or
    'wayland' when only one is. Raises RuntimeError when neither is set (no display: trying
    would only print SDL's XDG_RUNTIME_DIR noise and fall back to an invisible window)."""
    if os.environ.get('SDL_VIDEODRIVER') or sys.platform in ('win32', 'cygwin', 'darwin'):
        return None
    drivers = [name for name, variable in (('x11', 'DISPLAY'), ('wayland', 'WAYLAND_DISPLAY'))
               if os.environ.get(variable)]
    if not drivers:
        raise RuntimeError(f"render_mode='human' needs a display, but neither DISPLAY nor WAYLAND_DISPLAY "
                           f'is set; {_HEADLESS_HINT}')
    return drivers[0] if len(drivers) == 1 else None
