"""Draw the legend of rendered frames (what each shape and colour means) with mate's own renderer.

    SDL_VIDEODRIVER=dummy python docs/tools/render_legend.py [--output docs/images/legend.png]

One hand-made world holds an example of everything a frame can show: two cameras (one seen by a
target, one not; one tracking a target behind an obstacle's shadow, one seeing nothing), targets
with and without cargo, a high-capacity target, a target whose bounty is spent, a tracked
target, an obstacle, the four warehouse states and the message arrows of `RenderCommunication` (with and
without `kinds=True`: requests, replies and broadcasts).
The script renders it once (HUD off, 1600 pixels for crisp crops), cuts a square around each
example, and lays the crops out in a captioned grid, with the heads-up line of the same frame at
the bottom. Coordinates are world units (the terrain spans [-1000, 1000] on both axes).
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

import numpy as np

os.environ.setdefault('PYGAME_HIDE_SUPPORT_PROMPT', '1')

import pygame  # noqa: E402
import pygame.freetype  # noqa: E402

import mate  # noqa: E402
from mate.constants import WAREHOUSES  # noqa: E402
from mate.envs.render import Renderer  # noqa: E402

RENDER_SIZE = 1600
"""Pixels of the rendered frame the crops are cut from."""
LEGEND_WIDTH = 800
"""Pixels across the legend image."""
MARGIN, CAPTION_SIZE, TITLE_SIZE = 12, 13, 16
INK = (38, 38, 38)

CAMERAS = np.array([[-550.0, -450.0], [450.0, -450.0]])
"""Camera 0 looks up-right at a target past an obstacle; camera 1 looks right at nothing."""
CAMERA_VIEW = [(60.0, 60.0), (0.0, 120.0)]
"""(orientation, viewing angle) per camera, degrees."""
TARGETS = np.array([[-450.0, 450.0], [-150.0, 450.0], [150.0, 450.0], [450.0, 450.0],
                    [-550.0 + 400.0 * math.cos(math.radians(75.0)), -450.0 + 400.0 * math.sin(math.radians(75.0))],
                    [-150.0, 790.0], [150.0, 790.0], [-300.0, -820.0], [0.0, -820.0]])
TARGET_GOALS = [0, -1, 1, 3, 2, 0, 0, -1, -1]
"""Destination warehouse per target (-1: no cargo)."""
OBSTACLES = np.array([[-550.0 + 350.0 * math.cos(math.radians(45.0)), -450.0 + 350.0 * math.sin(math.radians(45.0)),
                       70.0], [150.0, 100.0, 90.0]])

CONFIG = {
    'name': 'legend', 'max_episode_steps': 2000, 'num_cargoes_per_target': 4, 'high_capacity_target_split': 0.0,
    'targets_start_with_cargoes': True, 'bounty_factor': 1.0, 'shuffle_entities': False, 'reward_type': 'dense',
    'camera': {'location': CAMERAS.tolist(), 'min_viewing_angle': 30.0, 'max_sight_range': 1000.0,
               'rotation_step': 5.0, 'zooming_step': 2.5, 'radius': 40.0},
    'target': {'location': TARGETS.tolist(), 'step_size': 20.0, 'sight_range': 450.0},
    'obstacle': {'location': OBSTACLES[:, :2].tolist(), 'radius': 70.0, 'transmittance': 0.0},
}

# (section title, thumbnail pixels, [(crop centre (x, y), crop half-width, caption), ...])
SECTIONS = [
    ('Cameras and their fields of view', 185, [
        (CAMERAS[1], 90.0, 'camera: the lens points where it looks; blue body: no target sees it'),
        (CAMERAS[0], 90.0, 'camera seen by a target (rust body)'),
        ((-260.0, -130.0), 400.0, 'field of view: whole sector light cyan; the part the camera sees green when it '
                                  'tracks a target; behind an obstacle only cyan (shadow)'),
        ((700.0, -450.0), 290.0, 'olive: the part a camera sees while it tracks no target'),
    ]),
    ('Targets and obstacles', 120, [
        (TARGETS[0], 75.0, 'target carrying cargo, coloured as its destination warehouse'),
        (TARGETS[1], 75.0, 'target without cargo (green)'),
        (TARGETS[2], 75.0, 'high-capacity target (capacity 2): no notch at the back'),
        (TARGETS[3], 75.0, 'white badge: bounty used up (cameras tracked it for too long)'),
        (TARGETS[4], 75.0, 'yellow disc: tracked, some camera sees it'),
        (OBSTACLES[1, :2], 130.0, 'obstacle: blocks movement and hides what lies behind it'),
    ]),
    ('Warehouses and messages', 120, [
        (WAREHOUSES[0], 110.0, 'warehouse with cargo to send (arrow out)'),
        (WAREHOUSES[1], 110.0, 'warehouse awaiting cargo (arrow in)'),
        (WAREHOUSES[2], 110.0, 'warehouse sending and awaiting'),
        (WAREHOUSES[3], 110.0, 'idle warehouse (pale, shutters)'),
        ((0.0, 790.0), 190.0, 'message between targets: red dashed arrow to the recipient'),
        ((330.0, -450.0), 170.0, 'message between cameras: blue dashed arrow'),
    ]),
    ('Message kinds (mate evaluate --render-communication)', 150, [
        ((-150.0, -820.0), 200.0, 'request (orange, dashed) from the left target, and the reply (purple, solid) '
                                  'it gets back in the same step'),
        ((0.0, 790.0), 190.0, 'broadcast: dashed in the team colour, as any message without the kinds'),
    ]),
]
HUD_CAPTION = ('heads-up line (top of every frame; env.render_hud / mate evaluate --no-hud turn it off): env name, '
               'episode step / step limit, coverage rate now, cargo delivered / all cargo')


def legend_world(renderer: Renderer) -> tuple[mate.MultiAgentTracking, dict]:
    """The legend's env and its world dict (headings set to face right); queues the message arrows
    of the world on `renderer`."""
    env = mate.RenderCommunication(mate.MultiAgentTracking(CONFIG, render_mode='rgb_array'))
    base = env.unwrapped
    env.reset(seed=0)
    world = base.get_world()
    for c, (orientation, viewing_angle) in enumerate(CAMERA_VIEW):
        world['camera_orientation'][c] = orientation
        world['camera_viewing_angle'][c] = viewing_angle
        world['camera_sight_range'][c] = math.sqrt(30.0 * 1000.0 ** 2 / viewing_angle)  # constant sector area
    world['obstacle_state'][:] = OBSTACLES
    state = world['target_state']
    state[:, :2] = TARGETS
    state[:, 5] = 1.0
    state[2, 5] = 2.0                                               # the high-capacity target
    state[:, 4] = CONFIG['target']['step_size'] / state[:, 5]
    state[:, 6:14] = 0.0
    for t, goal in enumerate(TARGET_GOALS):
        state[t, 3] = goal >= 0
        if goal >= 0:
            state[t, 6 + goal] = 1.0
    world['target_goal'][:] = TARGET_GOALS
    world['target_bounty'][:] = 50
    world['target_bounty'][3] = 0                                   # bounty spent
    remaining = np.zeros((4, 4), dtype=int)
    remaining[0, 1] = remaining[2, 3] = 1                           # warehouses 0 and 2 send
    world['remaining_cargoes'] = remaining
    world['awaiting_cargo_counts'] = np.array([0, 1, 1, 0])         # warehouses 1 and 2 await
    world['episode_step'] = 120
    base.set_world(world)
    world = base.get_world()
    world['target_heading'][:] = 0.0
    world['target_heading'][4] = 105.0
    env.camera_remaining[0, 1] = env.target_remaining[5, 6] = env.duration
    env.draw(base, renderer)
    kinds = mate.RenderCommunication(base, duration=1, kinds=True)     # request 7 -> 8, reply 8 -> 7
    kinds.remaining['request'][mate.Team.TARGET][7, 8] = kinds.remaining['reply'][mate.Team.TARGET][8, 7] = 1
    kinds.draw(base, renderer)
    return base, world


def wrapped(font, text: str, width: int) -> list[str]:
    """`text` broken into lines at most `width` pixels wide in `font`."""
    lines, line = [], ''
    for word in text.split():
        candidate = f'{line} {word}'.strip()
        if line and font.get_rect(candidate).width > width:
            lines.append(line)
            line = word
        else:
            line = candidate
    return lines + [line] if line else lines


def draw_legend(output: str | os.PathLike) -> Path:
    """Render the legend world, lay out the captioned crops and save a PNG at `output`."""
    renderer = Renderer('rgb_array', window_size=RENDER_SIZE, hud=False)
    env, world = legend_world(renderer)
    renderer.frame(world, transmittance=float(env.params.transmittance))
    scene = renderer.canvas.copy()
    hud = Renderer('rgb_array', window_size=LEGEND_WIDTH)
    hud.frame(world, name=env.name, max_episode_steps=env.max_episode_steps)
    hud_band = hud.canvas.subsurface((0, 0, LEGEND_WIDTH, hud.hud_height)).copy()

    pygame.freetype.init()
    caption_font = pygame.freetype.Font(None, CAPTION_SIZE)
    title_font = pygame.freetype.Font(None, TITLE_SIZE)
    title_font.strong = True
    blocks = []   # (x, y, surface or text, font or None) to draw, laid out top to bottom
    y = MARGIN
    for title, thumb, entries in SECTIONS:
        blocks.append((MARGIN, y, title, title_font))
        y += title_font.get_sized_height() + 6
        cell = (LEGEND_WIDTH - 2 * MARGIN) // len(entries)
        tallest = 0
        for i, (center, half, caption) in enumerate(entries):
            x = MARGIN + i * cell + (cell - thumb) // 2
            left, top = renderer.to_pixels(np.asarray(center, dtype=float) + [-half, half])
            size = 2.0 * half * renderer.scale
            square = pygame.Rect(round(left), round(top), round(size), round(size)).clip(scene.get_rect())
            crop = scene.subsurface(square)
            blocks.append((x, y, pygame.transform.smoothscale(crop, (thumb, thumb)), None))
            lines = wrapped(caption_font, caption, cell - 8)
            for k, line in enumerate(lines):
                blocks.append((MARGIN + i * cell + 4, y + thumb + 6 + k * caption_font.get_sized_height(), line,
                               caption_font))
            tallest = max(tallest, thumb + 6 + len(lines) * caption_font.get_sized_height())
        y += tallest + 14
    blocks.append((MARGIN, y, 'Heads-up line', title_font))
    y += title_font.get_sized_height() + 6
    blocks.append((0, y, hud_band, None))
    y += hud_band.get_height() + 4
    for line in wrapped(caption_font, HUD_CAPTION, LEGEND_WIDTH - 2 * MARGIN):
        blocks.append((MARGIN, y, line, caption_font))
        y += caption_font.get_sized_height()

    legend = pygame.Surface((LEGEND_WIDTH, y + MARGIN))
    legend.fill((255, 255, 255))
    for x, y, item, font in blocks:
        if font is None:
            legend.blit(item, (x, y))
            if item is not hud_band:
                frame = (x - 1, y - 1, item.get_width() + 2, item.get_height() + 2)
                pygame.draw.rect(legend, (190, 190, 190), frame, 1)
        else:
            font.render_to(legend, (x, y), item, INK)
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    pygame.image.save(legend, str(output))
    return output


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--output', default=str(Path(__file__).resolve().parents[2] / 'docs' / 'images' / 'legend.png'),
                        help='PNG to write (default docs/images/legend.png)')
    args = parser.parse_args(argv)
    print(f'legend written to {draw_legend(args.output)}')


if __name__ == '__main__':
    main()
