"""Draw the pictures of the documentation site with mate's own renderer, into docs/images/.

    SDL_VIDEODRIVER=dummy python docs/tools/docs_figures.py            # everything (about a minute)
    SDL_VIDEODRIVER=dummy python docs/tools/docs_figures.py presets    # one group: presets, concepts, ranges, gif, results

* presets: one frame per shipped preset (seed 0, after 40 steps of greedy play), docs/images/presets/;
* concepts: one annotated frame naming the parts of the game, docs/images/concepts.png;
* ranges: what one camera and one target observe, docs/images/observation-camera.png and
  observation-target.png;
* gif: greedy cameras against greedy targets on MATE-4v8-9, docs/images/greedy-play.gif;
* results: copies of the training and population figures of docs/tools/results/ (the site can only
  show files under docs/), docs/images/results/.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # run from a checkout without installing
    sys.path.insert(0, str(ROOT))
os.environ.setdefault('SDL_VIDEODRIVER', 'dummy')

import mate  # noqa: E402
from mate.envs.render import Renderer  # noqa: E402
from mate.tools.video import save_gif  # noqa: E402

IMAGES = ROOT / 'docs' / 'images'
SEED = 0
GALLERY_PIXELS = 360
DIAGRAM_PIXELS = 640
GIF_PIXELS = 320
GIF_STEPS = 300
GIF_EVERY = 5
RESULT_FIGURES = {
    'cameras-4v8-9.png': 'docs/tools/results/cameras-4v8-9.png',
    'targets-2v4-0.png': 'docs/tools/results/targets-2v4-0.png',
    'targets-4v8-0.png': 'docs/tools/results/targets-4v8-0.png',
    'targets-2v4-0-observability.png': 'docs/tools/results/targets-2v4-0-observability.png',
    'targets-4v8-0-communication.png': 'docs/tools/results/targets-4v8-0-communication.png',
    'cameras-4v8-9-communication.png': 'docs/tools/results/cameras-4v8-9-communication.png',
    'cameras-4v8-9-hrl.png': 'docs/tools/results/cameras-4v8-9-hrl.png',
    'psro-exploitability.png': 'docs/tools/results/psro/exploitability.png',
    'psro-meta-strategies-nash-seed0.png': 'docs/tools/results/psro/meta-strategies-nash-seed0.png',
}
"""docs/images/results/NAME -> its source, relative to the repository root."""

HIGHLIGHT = (1.0, 0.0, 0.6)
SEEN = (0.0, 0.65, 0.0)
UNSEEN = (0.45, 0.45, 0.45)


class GreedyMatch:
    """An env with greedy cameras and greedy targets, stepped together."""

    def __init__(self, config: str, seed: int = SEED) -> None:
        self.env = mate.make(f'{config}-v0')
        self.cameras = mate.GreedyCameraAgent(seed=seed).spawn(self.env.num_cameras)
        self.targets = mate.GreedyTargetAgent(seed=seed).spawn(self.env.num_targets)
        (self.camera_obs, self.target_obs), (self.camera_infos, self.target_infos) = self.env.reset(seed=seed)
        mate.group_reset(self.cameras, self.camera_obs)
        mate.group_reset(self.targets, self.target_obs)

    def step(self) -> bool:
        """One env step; False once the episode is over."""
        camera_action = mate.group_step(self.env, self.cameras, self.camera_obs, self.camera_infos)
        target_action = mate.group_step(self.env, self.targets, self.target_obs, self.target_infos)
        observations, _, terminated, truncated, infos = self.env.step((camera_action, target_action))
        self.camera_obs, self.target_obs = observations
        self.camera_infos, self.target_infos = infos
        return not (terminated or truncated)


def presets() -> list[Path]:
    """One frame per preset."""
    folder = IMAGES / 'presets'
    folder.mkdir(parents=True, exist_ok=True)
    renderer = Renderer(window_size=GALLERY_PIXELS)
    written = []
    for name in mate.list_presets():
        match = GreedyMatch(name)
        for _ in range(40):
            match.step()
        path = folder / f'{name}.png'
        _save_png(renderer.render(match.env), path)
        written.append(path)
    return written


def _ring(renderer, center, radius: float, color) -> None:
    renderer.circle(center, radius, color, filled=False, width=3.0)


def camera_view(env, renderer, camera: int = 0) -> None:
    """Mark what camera `camera` observes: the targets it tracks and the obstacles it knows."""
    world = renderer.world
    location = world['camera_state'][camera, :2]
    renderer.circle(location, 110.0, HIGHLIGHT, filled=False, width=4.0)
    for t, seen in enumerate(world['camera_target_view_mask'][camera]):
        _ring(renderer, world['target_state'][t, :2], 55.0, SEEN if seen else UNSEEN)
    for o, seen in enumerate(world['camera_obstacle_view_mask'][camera]):
        x, y, radius = world['obstacle_state'][o]
        if seen:
            renderer.circle((x, y), radius + 12.0, SEEN, filled=False, width=2.0)


def target_view(env, renderer, target: int = 0) -> None:
    """Mark what target `target` observes: its sight disc, the cameras, obstacles and targets in it."""
    world = renderer.world
    location = world['target_state'][target, :2]
    sight = world['target_state'][target, 2]
    renderer.circle(location, sight, HIGHLIGHT, alpha=0.12, layer='below')
    renderer.circle(location, sight, HIGHLIGHT, filled=False, width=3.0)
    renderer.circle(location, 70.0, HIGHLIGHT, filled=False, width=4.0)
    for c, seen in enumerate(world['target_camera_view_mask'][target]):
        _ring(renderer, world['camera_state'][c, :2], 90.0, SEEN if seen else UNSEEN)
    for t, seen in enumerate(world['target_target_view_mask'][target]):
        if t != target:
            _ring(renderer, world['target_state'][t, :2], 55.0, SEEN if seen else UNSEEN)
    for o, seen in enumerate(world['target_obstacle_view_mask'][target]):
        x, y, radius = world['obstacle_state'][o]
        if seen:
            renderer.circle((x, y), radius + 12.0, SEEN, filled=False, width=2.0)


def ranges() -> list[Path]:
    """The observation-range diagrams of camera 0 and target 0 (MATE-4v8-9, seed 0, step 60)."""
    match = GreedyMatch('MATE-4v8-9')
    for _ in range(60):
        match.step()
    renderer = Renderer(window_size=DIAGRAM_PIXELS)
    written = []
    for name, callback in (('observation-camera.png', camera_view), ('observation-target.png', target_view)):
        path = IMAGES / name
        _save_png(renderer.render(match.env, onetime_callbacks=[callback]), path)
        written.append(path)
    return written


def _label(draw, font, text: str, anchor_xy, text_xy, taken: list) -> None:
    """A text label near `text_xy`, moved down until it overlaps no box in `taken`, with a leader
    line to `anchor_xy` (pixels)."""
    x, y = float(text_xy[0]), float(text_xy[1])
    while True:
        box = draw.textbbox((x, y), text, font=font, anchor='mm')
        box = (box[0] - 5, box[1] - 4, box[2] + 5, box[3] + 4)
        if not any(box[0] < o[2] and o[0] < box[2] and box[1] < o[3] and o[1] < box[3] for o in taken):
            break
        y += 8.0
    taken.append(box)
    draw.line([(x, y), tuple(anchor_xy)], fill=(60, 60, 60), width=2)
    draw.rectangle(box, fill=(255, 255, 255), outline=(60, 60, 60))
    draw.text((x, y), text, fill=(20, 20, 20), font=font, anchor='mm')


def concepts() -> list[Path]:
    """One frame of MATE-4v8-9 with the parts of the game named."""
    from PIL import Image, ImageDraw, ImageFont

    match = GreedyMatch('MATE-4v8-9')
    for _ in range(60):
        match.step()
    renderer = Renderer(window_size=DIAGRAM_PIXELS)
    frame = renderer.render(match.env)
    world = match.env.get_world()
    image = Image.fromarray(frame)
    draw = ImageDraw.Draw(image)
    font = ImageFont.load_default(size=15)
    pixel = renderer.to_pixels
    camera = int(np.argmax(world['camera_target_view_mask'].sum(axis=1)))   # the camera seeing most targets
    tracked = np.flatnonzero(world['camera_target_view_mask'].any(axis=0))
    hidden = np.flatnonzero(~world['camera_target_view_mask'].any(axis=0))
    camera_xy = pixel(world['camera_state'][camera, :2])
    centre = np.array([DIAGRAM_PIXELS / 2, DIAGRAM_PIXELS / 2])
    taken: list = []

    def away(xy, distance=70.0):
        """A point `distance` pixels from `xy`, towards the centre of the frame."""
        direction = centre - xy
        return xy + distance * direction / max(np.linalg.norm(direction), 1e-9)

    _label(draw, font, 'camera (fixed; turns and zooms)', camera_xy, away(camera_xy, 90), taken)
    sector_xy = pixel(world['camera_state'][camera, :2] + 0.6 * world['camera_state'][camera, 3:5])
    _label(draw, font, 'field of view', sector_xy, away(sector_xy, 50), taken)
    if len(tracked):
        xy = pixel(world['target_state'][tracked[0], :2])
        _label(draw, font, 'tracked target', xy, away(xy, 80), taken)
    if len(hidden):
        xy = pixel(world['target_state'][hidden[-1], :2])
        _label(draw, font, 'target out of sight', xy, away(xy, 80), taken)
    obstacle = int(np.argmax(world['obstacle_state'][:, 2]))
    xy = pixel(world['obstacle_state'][obstacle, :2])
    _label(draw, font, 'obstacle', xy, away(xy, 80), taken)
    warehouse_xy = pixel(mate.WAREHOUSES[0])
    _label(draw, font, 'warehouse (cargo in and out)', warehouse_xy, warehouse_xy + np.array([-150.0, 60.0]), taken)
    path = IMAGES / 'concepts.png'
    image.save(path, optimize=True)
    return [path]


def gif() -> list[Path]:
    """A short GIF of greedy play."""
    match = GreedyMatch('MATE-4v8-9')
    renderer = Renderer(window_size=GIF_PIXELS)
    frames = [renderer.render(match.env)]
    for step in range(1, GIF_STEPS + 1):
        if not match.step():
            break
        if step % GIF_EVERY == 0:
            frames.append(renderer.render(match.env))
    return [save_gif(frames, IMAGES / 'greedy-play.gif', fps=12)]


def results() -> list[Path]:
    """Copies of the result figures."""
    folder = IMAGES / 'results'
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, source in RESULT_FIGURES.items():
        shutil.copyfile(ROOT / source, folder / name)
        written.append(folder / name)
    return written


def _save_png(frame: np.ndarray, path: Path) -> None:
    from PIL import Image
    Image.fromarray(frame).save(path, optimize=True)


GROUPS = {'presets': presets, 'concepts': concepts, 'ranges': ranges, 'gif': gif, 'results': results}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('groups', nargs='*', help=f'what to draw: {", ".join(GROUPS)} (default: everything)')
    args = parser.parse_args(argv)
    unknown = [group for group in args.groups if group not in GROUPS]
    if unknown:
        parser.error(f'unknown group {unknown[0]!r}; choose from {", ".join(GROUPS)}')
    for group in args.groups or GROUPS:
        for path in GROUPS[group]():
            print(f'{path.relative_to(ROOT)}  {path.stat().st_size / 1024:.0f} KB')
    return 0


if __name__ == '__main__':
    sys.exit(main())
