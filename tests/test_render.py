"""Rendering (`mate.envs.render`, `env.render()`) and the GIF/video writers (`mate.tools.video`), spec §8.

The scene tests load a hand-made world with `set_world` and check the colours of single
pixels: the frame must show the right things in the right places, not only have a shape.
"""

from __future__ import annotations

import itertools
import math
import os
import subprocess
import sys
from pathlib import Path

os.environ['SDL_VIDEODRIVER'] = 'dummy'  # headless: must precede pygame's display initialisation
os.environ['SDL_AUDIODRIVER'] = 'dummy'
os.environ.setdefault('PYGAME_HIDE_SUPPORT_PROMPT', '1')

import numpy as np
import pytest

import pygame  # noqa: E402,F401  (part of the test extra: a missing renderer must fail, not skip)

import mate
from mate.constants import WAREHOUSE_RADIUS, WAREHOUSES
from mate.evaluation.evaluate import FrameRecorder
from mate.envs.render import MIN_TARGET_PIXELS, WAREHOUSE_COLORS, Renderer, hud_line, sector_polygon, visible_region
from mate.tools.video import save_gif, save_video

SIZE = 800
BOUND = 1050.0

# One camera at (0, -600) looking up (90 deg) with a 60 deg sector of radius sqrt(30 * 1000^2 / 60);
# an opaque obstacle at the right edge of the sector; one loaded target (goal warehouse 2) in view.
CAMERA, OBSTACLE, TARGET = (0.0, -600.0), (230.0, -250.0, 80.0), (-200.0, -150.0)
VIEWING_ANGLE = 60.0
SIGHT_RANGE = math.sqrt(30.0 * 1000.0 ** 2 / VIEWING_ANGLE)
SCENE_CONFIG = {
    'name': 'render-scene', 'max_episode_steps': 100, 'num_cargoes_per_target': 4,
    'high_capacity_target_split': 0.0, 'targets_start_with_cargoes': True, 'bounty_factor': 1.0,
    'shuffle_entities': False, 'reward_type': 'dense',
    'camera': {'location': [list(CAMERA)], 'min_viewing_angle': 30.0, 'max_sight_range': 1000.0,
               'rotation_step': 5.0, 'zooming_step': 2.5, 'radius': 40.0},
    'target': {'location': [list(TARGET)], 'step_size': 20.0, 'sight_range': 500.0},
    'obstacle': {'location': [list(OBSTACLE[:2])], 'radius': OBSTACLE[2], 'transmittance': 0.0},
}

# Expected colours (0..255): white blended with the sector cyan (alpha 0.1), then green/olive (0.25).
WHITE = np.array([255, 255, 255])
CYAN_TINT = WHITE * 0.9 + np.array([0, 153, 204]) * 0.1
GREEN_TINT = CYAN_TINT * 0.75 + np.array([0, 153, 0]) * 0.25
OLIVE_TINT = CYAN_TINT * 0.75 + np.array([153, 153, 0]) * 0.25
OBSTACLE_GREY = np.array([76.5, 76.5, 76.5])
YELLOW = np.array([255, 255, 0])
RUST, BLUE = np.array([153, 51, 25.5]), np.array([25.5, 51, 153])


def pixel(frame: np.ndarray, x: float, y: float) -> np.ndarray:
    """The RGB of the pixel containing world point (x, y)."""
    column = int((x + BOUND) / (2 * BOUND) * SIZE)
    row = int((BOUND - y) / (2 * BOUND) * SIZE)
    return frame[row, column].astype(float)


def assert_color(frame, x, y, expected, tolerance=4.0):
    got = pixel(frame, x, y)
    assert np.abs(got - np.asarray(expected, dtype=float)).max() <= tolerance, \
        f'pixel at world ({x}, {y}) is {got.tolist()}, expected about {np.round(expected, 1).tolist()}'


def polar(rho: float, degrees: float, origin=CAMERA) -> tuple[float, float]:
    return (origin[0] + rho * math.cos(math.radians(degrees)), origin[1] + rho * math.sin(math.radians(degrees)))


def make_scene(transmittance: float = 0.0, render_mode: str = 'rgb_array', **changes):
    config = {**SCENE_CONFIG, 'obstacle': {**SCENE_CONFIG['obstacle'], 'transmittance': transmittance}}
    env = mate.MultiAgentTracking(config, render_mode=render_mode)
    env.reset(seed=0)
    set_scene(env, **changes)
    return env


def set_scene(env, orientation: float = 90.0, target=TARGET, goal: int = 2, bounty: int = 50,
              remaining=None, awaiting=None):
    world = env.get_world()
    world['camera_state'][0, :2] = CAMERA
    world['camera_orientation'][:] = orientation
    world['camera_viewing_angle'][:] = VIEWING_ANGLE
    world['camera_sight_range'][:] = SIGHT_RANGE
    world['obstacle_state'][0] = OBSTACLE
    state = world['target_state']
    state[0, :2] = target
    state[0, 3] = goal >= 0
    state[0, 4:6] = 20.0, 1.0
    state[0, 6:10] = 0.0
    if goal >= 0:
        state[0, 6 + goal] = 1.0
    state[0, 10:14] = 0.0
    world['target_goal'][:] = goal
    world['target_bounty'][:] = bounty
    world['remaining_cargoes'] = np.eye(4, k=1, dtype=int) if remaining is None else np.asarray(remaining)
    world['awaiting_cargo_counts'] = np.ones(4, dtype=int) if awaiting is None else np.asarray(awaiting)
    env.set_world(world)
    return world


@pytest.fixture()
def scene():
    env = make_scene()
    yield env
    env.close()


# --------------------------------------------------------------------------- env API

def test_render_modes_and_frame_format(scene):
    assert mate.MultiAgentTracking.metadata['render_modes'] == ['human', 'rgb_array']
    assert scene.render_mode == 'rgb_array' and scene.render_fps == 60
    frame = scene.render()
    assert isinstance(frame, np.ndarray) and frame.shape == (SIZE, SIZE, 3) and frame.dtype == np.uint8
    assert frame.flags.writeable and frame.flags.c_contiguous


def test_unknown_render_mode_is_refused_with_a_clear_error():
    with pytest.raises(ValueError, match="render_mode='ansi'.*'human'.*'rgb_array'"):
        mate.make('MATE-1v1-0-v0', render_mode='ansi')


def test_render_without_render_mode_warns_and_returns_none():
    env = mate.make('MATE-1v1-0-v0')
    env.reset(seed=0)
    with pytest.warns(UserWarning, match='render_mode'):
        assert env.render() is None
    assert env.viewer is None


def test_gymnasium_make_passes_the_render_mode():
    import gymnasium
    env = gymnasium.make('MATE-1v1-0-v0', render_mode='rgb_array')
    env.reset(seed=0)
    assert env.render().shape == (SIZE, SIZE, 3)
    env.close()


def test_import_mate_does_not_import_pygame():
    code = 'import sys, mate; mate.make("MATE-4v8-9-v0"); print("pygame" in sys.modules)'
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == 'False'


def test_human_mode_opens_and_closes_a_window():
    env = make_scene(render_mode='human')
    env.render_fps = None  # do not throttle the test
    try:
        assert env.render() is None
        assert env.viewer is not None and env.viewer.is_open
        env.step(env.action_space.sample())
        assert env.render() is None
        import pygame
        assert pygame.display.get_surface() is not None
        assert pygame.display.get_surface().get_size() == (SIZE, SIZE)
    finally:
        env.close()
    assert env.viewer is None
    import pygame
    assert not pygame.display.get_init()
    env.close()  # closing twice is harmless


# --------------------------------------------------------------------------- pixels of a hand-made scene

def test_background_border_and_obstacle(scene):
    frame = scene.render()
    assert_color(frame, -500.0, 500.0, WHITE, tolerance=0)           # far from everything
    assert_color(frame, 0.0, -1040.0, WHITE, tolerance=0)            # margin outside the terrain (the HUD is on top)
    assert pixel(frame, 1000.0, 0.0).max() < 60                      # terrain border: black
    assert pixel(frame, 0.0, -1000.0).max() < 60
    assert pixel(frame, -1000.0, 300.0).max() < 60
    assert_color(frame, OBSTACLE[0] + 20, OBSTACLE[1], OBSTACLE_GREY)  # obstacle centre, outside the sector


def test_visible_sector_is_green_and_the_shadow_only_cyan(scene):
    frame = scene.render()
    assert scene.camera_target_view_mask[0, 0]
    assert_color(frame, *polar(500.0, 90.0), GREEN_TINT)      # in view, unoccluded
    assert_color(frame, *polar(300.0, 110.0), GREEN_TINT)
    assert_color(frame, *polar(400.0, 119.0), GREEN_TINT)     # up to the sector's edges
    assert_color(frame, *polar(250.0, 61.0), GREEN_TINT)
    assert_color(frame, *polar(600.0, 62.0), CYAN_TINT)       # in the sector, behind the obstacle
    assert_color(frame, *polar(650.0, 63.0), CYAN_TINT)
    assert_color(frame, *polar(500.0, 125.0), WHITE, 0)       # just outside the sector (edge at 120 deg)
    assert_color(frame, *polar(730.0, 90.0), WHITE, 0)        # beyond the sight range (707)


def test_sector_without_tracked_target_is_olive():
    env = make_scene(target=(-500.0, 600.0))
    assert not env.camera_target_view_mask.any()
    frame = env.render()
    assert_color(frame, *polar(500.0, 90.0), OLIVE_TINT)
    assert_color(frame, *polar(600.0, 62.0), CYAN_TINT)
    assert_color(frame, *polar(33.0, 0.0), BLUE, 6)           # camera body: no target perceives it
    assert_color(frame, -500.0, 600.0, np.array([149, 117, 205]), 0)   # the untracked target ...
    assert_color(frame, -500.0 + 30.5, 600.0, WHITE, 0)                # ... has no yellow marker


def test_transparent_obstacles_cast_no_shadow():
    env = make_scene(transmittance=1.0)
    frame = env.render()
    assert_color(frame, *polar(600.0, 62.0), GREEN_TINT)
    assert_color(frame, *polar(500.0, 90.0), GREEN_TINT)


def test_target_marker_and_camera_body(scene):
    frame = scene.render()
    assert_color(frame, *TARGET, np.round(WAREHOUSE_COLORS[2] * 255), 0)   # goal warehouse 2: purple
    for angle in (0.0, 90.0, 200.0, 300.0):                                 # yellow ring around it
        assert_color(frame, *polar(30.5, angle, origin=TARGET), YELLOW, 0)
    assert_color(frame, *polar(33.0, 180.0), RUST, 6)   # a target perceives the camera: rust body
    assert pixel(frame, *polar(43.0, 90.0)).max() < 120  # the dark lens ahead of the body


def test_unloaded_target_is_green_and_bountyless_target_has_a_white_badge():
    env = make_scene(goal=-1)
    assert_color(env.render(), *TARGET, np.array([51, 153, 51]), 0)
    set_scene(env, bounty=0)
    badge = WHITE * 0.66 + np.round(WAREHOUSE_COLORS[2] * 255) * 0.34
    frame = env.render()
    assert_color(frame, *TARGET, badge)
    env.close()


@pytest.mark.parametrize('active', [True, False])
def test_warehouse_colours(active):
    awaiting = np.ones(4, dtype=int) if active else np.zeros(4, dtype=int)
    remaining = np.eye(4, k=1) if active else np.zeros((4, 4))
    env = make_scene(remaining=remaining, awaiting=awaiting)
    frame = env.render()
    alpha = 0.6 if active else 0.3
    for w, (cx, cy) in enumerate(WAREHOUSES):
        expected = WHITE * (1 - alpha) + np.round(WAREHOUSE_COLORS[w] * 255) * alpha
        for sx, sy in ((1, 1), (-1, 1)):   # upper corners of the square, clear of the icon
            assert_color(frame, cx + sx * 0.8 * WAREHOUSE_RADIUS, cy + sy * 0.8 * WAREHOUSE_RADIUS, expected)
        assert_color(frame, cx, cy - 0.25 * 1.8 * WAREHOUSE_RADIUS, np.round(WAREHOUSE_COLORS[w] * 255), 0)  # door
    env.close()


def test_warehouse_icons_show_sending_and_receiving():
    arrow_out = (0.36 * 135.0, -0.12 * 135.0)   # icon-local point on the outgoing arrow's shaft
    arrow_in = (-0.40 * 135.0, -0.12 * 135.0)   # ... on the incoming arrow's shaft
    remaining = np.zeros((4, 4))
    remaining[0, 1] = 1                          # warehouse 0 sends, warehouse 1 receives
    env = make_scene(remaining=remaining, awaiting=[0, 1, 0, 0])
    frame = env.render()
    dark = lambda w, p: pixel(frame, WAREHOUSES[w][0] + p[0], WAREHOUSES[w][1] + p[1]).max() < 90
    assert dark(0, arrow_out) and not dark(0, arrow_in)
    assert dark(1, arrow_in) and not dark(1, arrow_out)
    assert not dark(2, arrow_in) and not dark(2, arrow_out)
    env.close()


# --------------------------------------------------------------------------- frames over time

def test_same_state_renders_identically_and_steps_change_the_frame():
    env = mate.make('MATE-4v8-9-v0', render_mode='rgb_array')
    env.reset(seed=7)
    first = env.render()
    assert np.array_equal(first, env.render())
    frames = [first]
    for _ in range(3):
        env.step(env.action_space.sample())
        frames.append(env.render())
    for before, after in itertools.pairwise(frames):
        assert not np.array_equal(before, after)
    assert np.array_equal(frames[-1], env.render())
    env.close()


# --------------------------------------------------------------------------- callbacks and primitives

def test_callbacks_draw_in_world_coordinates_on_their_layer(scene):
    calls = []

    def communication(env, renderer):
        calls.append((env, renderer.world['camera_state'].shape))
        renderer.line((-600.0, 0.0), (-300.0, 0.0), (1.0, 0.0, 0.0), width=5.0, layer='below')
        renderer.dashed_arrow((-600.0, 300.0), (-300.0, 300.0), (0.0, 0.0, 1.0), alpha=1.0, width=3.0)

    scene.add_render_callback('communication', communication)
    frame = scene.render()
    assert calls == [(scene, (1, 9))]
    assert_color(frame, -450.0, 0.0, (255, 0, 0), 0)
    row = int((BOUND - 300.0) / (2 * BOUND) * SIZE)
    columns = [int((x + BOUND) / (2 * BOUND) * SIZE) for x in (-590.0, -320.0)]
    line = frame[row, columns[0]:columns[1]]
    blue = (line[:, 2] > 200) & (line[:, 0] < 50)
    white = (line == 255).all(axis=1)
    assert blue.sum() > 30 and white.sum() > 30           # dashes and gaps
    # the 'below' layer lies under the cameras' sectors: a line through the sector is tinted
    scene.add_render_callback('communication', lambda env, r: r.line(
        polar(100.0, 90.0), polar(600.0, 90.0), (1.0, 0.0, 0.0), width=5.0, layer='below'))
    frame = scene.render()
    tinted = np.array([255, 0, 0]) * 0.9 * 0.75 + np.array([0, 153, 204]) * 0.1 * 0.75 + np.array([0, 153, 0]) * 0.25
    assert_color(frame, *polar(400.0, 90.0), tinted)
    scene.render_callbacks.clear()
    assert_color(scene.render(), -450.0, 0.0, WHITE, 0)   # primitives last one frame only


def test_onetime_callbacks_and_shapes(scene):
    def draw(env, renderer):
        renderer.circle((-500.0, 500.0), 50.0, (0.0, 0.0, 1.0))
        renderer.circle((500.0, 500.0), 50.0, (0.0, 0.0, 1.0), alpha=0.5)
        renderer.polygon([(-700, -700), (-600, -700), (-600, -600)], (1.0, 0.0, 1.0), filled=False, width=3.0)

    frame = scene.render(onetime_callbacks=[draw])
    assert_color(frame, -500.0, 500.0, (0, 0, 255), 0)
    assert_color(frame, 500.0, 500.0, (127.5, 127.5, 255), 2)
    assert_color(frame, -650.0, -700.0, (255, 0, 255), 0)   # an edge of the outline
    assert_color(frame, -620.0, -680.0, WHITE, 0)           # inside it: not filled
    assert_color(scene.render(), -500.0, 500.0, WHITE, 0)


def test_primitives_validate_their_arguments():
    renderer = Renderer('rgb_array')
    with pytest.raises(ValueError, match='color'):
        renderer.line((0, 0), (1, 1), (255, 0, 0))
    with pytest.raises(ValueError, match='layer'):
        renderer.line((0, 0), (1, 1), (1, 0, 0), layer='middle')
    with pytest.raises(ValueError, match='barbs'):
        renderer.arrow((0, 0), (1, 1), (1, 0, 0), barbs='three')
    with pytest.raises(ValueError, match='dash'):
        renderer.dashed_arrow((0, 0), (1, 1), (1, 0, 0), dash=0)
    with pytest.raises(ValueError, match='mode'):
        Renderer('ansi')


def test_a_rendering_env_can_be_copied_and_pickled(scene):
    import copy
    import pickle
    first = scene.render()
    for clone in (copy.deepcopy(scene), pickle.loads(pickle.dumps(scene))):
        assert np.array_equal(clone.render(), first)
        clone.close()


def test_pixel_and_world_coordinates_round_trip():
    renderer = Renderer('rgb_array')
    np.testing.assert_allclose(renderer.to_pixels([[-BOUND, BOUND], [BOUND, -BOUND], [0, 0]]),
                               [[0, 0], [SIZE, SIZE], [SIZE / 2, SIZE / 2]])
    points = np.random.default_rng(0).uniform(-1000, 1000, (10, 2))
    np.testing.assert_allclose(renderer.to_world(renderer.to_pixels(points)), points)


# --------------------------------------------------------------------------- geometry

def test_visible_region_stops_at_the_first_disc_and_respects_the_clamps():
    center = np.array([0.0, 0.0])
    region = visible_region(center, 0.0, 90.0, 500.0, 40.0, [[200.0, 0.0, 50.0]], max_sight_range=1000.0)
    assert np.array_equal(region[0], center)
    ends = region[1:] - center
    angles = np.degrees(np.arctan2(ends[:, 1], ends[:, 0]))
    lengths = np.hypot(ends[:, 0], ends[:, 1])
    assert np.all(np.diff(angles) > 0) and angles[0] == pytest.approx(-45.0) and angles[-1] == pytest.approx(45.0)
    ahead = np.argmin(np.abs(angles))
    assert lengths[ahead] == pytest.approx(150.0)                       # front of the disc
    half_width = math.degrees(math.asin(50.0 / 200.0))
    assert np.all(lengths[np.abs(angles) > half_width + 1e-6] == pytest.approx(500.0))
    inside = np.abs(angles) < half_width - 1e-6
    assert np.all(lengths[inside] < 200.0)
    exact = 200.0 * np.cos(np.radians(angles[inside])) - np.sqrt(
        50.0 ** 2 - (200.0 * np.sin(np.radians(angles[inside]))) ** 2)
    np.testing.assert_allclose(lengths[inside], exact, atol=1e-6)
    # camera inside a disc: blind, every ray clamped up to the camera radius
    blind = visible_region(center, 0.0, 90.0, 500.0, 40.0, [[10.0, 0.0, 50.0]])
    assert np.allclose(np.hypot(*(blind[1:] - center).T), 40.0)
    # max_sight_range caps the rays (before the clamp to the sight range)
    capped = visible_region(center, 0.0, 90.0, 500.0, 40.0, [], max_sight_range=300.0)
    assert np.allclose(np.hypot(*capped[1:].T), 300.0)


@pytest.mark.parametrize('seed', range(5))
def test_visible_region_keeps_the_sector_edges_with_discs_around(seed):
    rng = np.random.default_rng(seed)
    discs = np.column_stack([rng.uniform(-800, 800, (6, 2)), rng.uniform(20, 90, 6)])
    for orientation in rng.uniform(-180, 180, 20):
        viewing_angle = rng.uniform(30, 180)
        region = visible_region((0.0, 0.0), orientation, viewing_angle, 700.0, 40.0, discs, arc_step=2.0)
        ends = region[1:]
        offsets = (np.degrees(np.arctan2(ends[:, 1], ends[:, 0])) - orientation + 180.0) % 360.0 - 180.0
        assert offsets[0] == pytest.approx(-viewing_angle / 2) and offsets[-1] == pytest.approx(viewing_angle / 2)
        assert np.all(np.diff(offsets) > 0)


def test_sector_polygon_spans_the_viewing_angle():
    polygon = sector_polygon((100.0, 50.0), 170.0, 40.0, 300.0)
    ends = polygon[1:] - (100.0, 50.0)
    assert np.allclose(np.hypot(*ends.T), 300.0)
    angles = np.degrees(np.arctan2(ends[:, 1], ends[:, 0])) % 360.0
    assert angles.min() == pytest.approx(150.0) and angles.max() == pytest.approx(190.0)


# --------------------------------------------------------------------------- GIF / video files

def rendered_frames(count: int = 4):
    env = mate.make('MATE-2v2-9-v0', render_mode='rgb_array')
    env.reset(seed=0)
    frames = [env.render()]
    for _ in range(count - 1):
        env.step(env.action_space.sample())
        frames.append(env.render())
    return frames


def test_gif_round_trip(tmp_path):
    from PIL import Image
    frames = rendered_frames(5)
    path = save_gif(frames, tmp_path / 'episode.gif', fps=20)
    with Image.open(path) as image:
        assert image.format == 'GIF' and image.n_frames == 5 and image.size == (SIZE, SIZE)
        assert image.info['duration'] == 50 and image.info['loop'] == 0
        image.seek(2)
        decoded = np.asarray(image.convert('RGB'))
    assert np.abs(decoded.astype(int) - frames[2]).mean() < 3.0   # palette quantisation only


def test_gif_frames_decode_exactly_and_many_colours_fall_back_to_the_nearest(tmp_path):
    from PIL import Image
    frames = rendered_frames(40)
    frames[30] = frames[30].copy()
    frames[30][2:4, 2:4] = (10, 20, 250)      # a colour of one frame only
    path = save_gif(frames, tmp_path / 'episode.gif')
    distinct = [f for i, f in enumerate(frames) if i == 0 or not np.array_equal(f, frames[i - 1])]  # repeats merge
    with Image.open(path) as image:
        assert image.n_frames == len(distinct) > 20
        for index, frame in enumerate(distinct):
            image.seek(index)
            np.testing.assert_array_equal(np.asarray(image.convert('RGB')), frame)   # < 256 colours: exact
    rng = np.random.default_rng(0)
    noise = [rng.integers(0, 256, (16, 16, 3), dtype=np.uint8) for _ in range(3)]   # 768 colours: median cut
    path = save_gif(noise, tmp_path / 'noise.gif')
    with Image.open(path) as image:
        image.seek(1)
        error = np.abs(np.asarray(image.convert('RGB')).astype(int) - noise[1])
    assert error.mean() < 40 and (error == 0).mean() < 0.9


def test_save_video_writes_a_gif_by_suffix(tmp_path):
    from PIL import Image
    path = save_video(iter(rendered_frames(3)), tmp_path / 'episode.gif', fps=10)
    with Image.open(path) as image:
        assert image.n_frames == 3


def test_mp4_round_trip(tmp_path):
    import imageio_ffmpeg  # noqa: F401  (part of the test extra)
    import imageio.v3 as iio
    frames = rendered_frames(3)
    path = save_video(frames, tmp_path / 'episode.mp4', fps=10)
    video = iio.imread(path)
    assert video.shape == (3, SIZE, SIZE, 3)
    assert np.abs(video[1].astype(int) - frames[1]).mean() < 5.0


def test_writers_give_clear_errors(tmp_path):
    frame = np.zeros((8, 8, 3), dtype=np.uint8)
    with pytest.raises(ValueError, match='empty'):
        save_gif([], tmp_path / 'a.gif')
    with pytest.raises(ValueError, match='empty'):
        save_video(iter([]), tmp_path / 'a.mp4')
    with pytest.raises(FileNotFoundError, match='does not exist'):
        save_gif([frame], tmp_path / 'missing' / 'a.gif')
    with pytest.raises(ValueError, match='.gif'):
        save_gif([frame], tmp_path / 'a.png')
    with pytest.raises(ValueError, match='.mp4'):
        save_video([frame], tmp_path / 'a.txt')
    with pytest.raises(TypeError, match='uint8'):
        save_gif([frame.astype(float)], tmp_path / 'a.gif')
    with pytest.raises(ValueError, match='same size'):
        save_gif([frame, np.zeros((4, 4, 3), dtype=np.uint8)], tmp_path / 'a.gif')
    with pytest.raises(ValueError, match='fps'):
        save_gif([frame], tmp_path / 'a.gif', fps=0)
    with pytest.raises(ValueError, match='single frame'):
        save_gif(frame, tmp_path / 'a.gif')
    assert not list(tmp_path.iterdir())


# --------------------------------------------------------------------------- heads-up line, frame sizes

ROOT = Path(__file__).resolve().parents[1]
REFERENCE_FRAME = Path(__file__).parent / 'data' / 'render-scene-800.png'
"""The scene (`make_scene()`) as rendered before the HUD and the small-frame minimum sizes existed."""


def load_png(path) -> np.ndarray:
    from PIL import Image
    with Image.open(path) as image:
        return np.asarray(image.convert('RGB'))


def test_hud_line_summarises_step_coverage_and_cargo(scene):
    world = scene.get_world()   # one target carrying 1 unit, 3 units waiting, none delivered; it is tracked
    assert hud_line(world, scene.name, scene.max_episode_steps) == \
        'render-scene | step 0/100 | coverage 1.00 | delivered 0/4'
    world['episode_step'], world['num_delivered_cargoes'] = 37, 5
    assert hud_line(world) == 'step 37 | coverage 1.00 | delivered 5/9'


def test_hud_changes_only_its_band_and_follows_the_episode(scene):
    with_hud = scene.render()
    band = scene.viewer.hud_height
    assert 10 <= band <= 25
    assert (with_hud[:band].max(axis=2) < 100).sum() > 100            # dark text in the band
    scene.render_hud = False
    without = scene.render()
    changed_rows = np.flatnonzero((with_hud != without).any(axis=(1, 2)))
    assert changed_rows.size and changed_rows.max() < band
    scene.render_hud = True
    world = scene.get_world()
    world['episode_step'] = 57
    scene.set_world(world)
    later = scene.render()
    assert not np.array_equal(later[:band], with_hud[:band]) and np.array_equal(later[band:], with_hud[band:])


def test_without_hud_the_frame_is_the_one_from_before_the_hud(scene):
    reference = load_png(REFERENCE_FRAME)
    scene.render_hud = False
    assert np.array_equal(scene.render(), reference)
    assert np.array_equal(Renderer('rgb_array', hud=False).frame(scene.get_world()), reference)
    assert not np.array_equal(Renderer('rgb_array').frame(scene.get_world()), reference)


def test_hud_setting_survives_pickling():
    import pickle
    assert pickle.loads(pickle.dumps(Renderer('rgb_array', hud=False))).hud is False
    assert pickle.loads(pickle.dumps(Renderer('rgb_array'))).hud is True


def test_frame_recorder_size_hud_and_step_limit(scene):
    recorders = [FrameRecorder(every=1), FrameRecorder(every=1, max_episode_steps=50),
                 FrameRecorder(every=1, max_episode_steps=500), FrameRecorder(every=1, hud=False)]
    for recorder in recorders:
        recorder(scene, 0)
    world = scene.get_world()
    expected = [Renderer('rgb_array', 600).frame(world, 0.0, scene.name, 100),
                Renderer('rgb_array', 600).frame(world, 0.0, scene.name, 50),   # the evaluation's cap ...
                Renderer('rgb_array', 600).frame(world, 0.0, scene.name, 100),  # ... unless above the env's
                Renderer('rgb_array', 600, hud=False).frame(world)]
    assert recorders[0].frames[0].shape == (600, 600, 3)
    for recorder, frame in zip(recorders, expected):
        assert np.array_equal(recorder.frames[0], frame)
    assert not np.array_equal(expected[0], expected[1])


def test_small_frames_draw_targets_and_cameras_at_a_minimum_size():
    env = make_scene(target=(-500.0, 600.0))         # an untracked purple target, a blue camera body
    renderer = Renderer('rgb_array', window_size=200, hud=False)   # true sizes: target 4.7 px, camera radius 3.8 px
    frame = renderer.render(env).astype(int)

    def pixels_of(color, center, reach: int = 20) -> np.ndarray:
        column, row = renderer.to_pixels(center).astype(int)
        window = frame[row - reach:row + reach, column - reach:column + reach]
        rows, columns = np.nonzero(np.abs(window - np.round(np.asarray(color) * 255)).max(axis=2) <= 1)
        return np.column_stack([columns, rows]) + [column - reach + 0.5, row - reach + 0.5]

    target = pixels_of(WAREHOUSE_COLORS[2], (-500.0, 600.0))
    length = np.hypot(*(target[:, None] - target[None]).transpose(2, 0, 1)).max()
    assert MIN_TARGET_PIXELS - 2.0 <= length <= MIN_TARGET_PIXELS + 1.0
    body = pixels_of((0.1, 0.2, 0.6), CAMERA) - renderer.to_pixels(CAMERA)
    assert np.hypot(body[:, 0], body[:, 1]).max() >= 6.0
    env.close()


HEADLESS_RENDER = """
import mate
env = mate.make('MATE-1v1-0-v0', render_mode='human')
env.reset(seed=0)
try:
    env.render()
except RuntimeError as error:
    print(error)
else:
    print('no error')
"""


@pytest.mark.slow
@pytest.mark.parametrize('display', [{}, {'DISPLAY': ':9999'}, {'WAYLAND_DISPLAY': 'mate-test-no-such-display'}],
                         ids=['no display', 'no X server', 'no Wayland compositor'])
def test_human_mode_without_a_display_fails_with_one_clear_line(display):
    environment = {key: value for key, value in os.environ.items()
                   if key not in ('DISPLAY', 'WAYLAND_DISPLAY', 'SDL_VIDEODRIVER', 'XDG_RUNTIME_DIR')}
    out = subprocess.run([sys.executable, '-c', HEADLESS_RENDER], env={**environment, **display},
                         capture_output=True, text=True, check=True)
    message = out.stdout.strip()
    assert message.startswith("render_mode='human' ") and '\n' not in message
    assert "render_mode='rgb_array'" in message and 'SDL_VIDEODRIVER=dummy' in message
    assert 'XDG_RUNTIME_DIR' not in out.stderr and 'Traceback' not in out.stderr


def test_legend_script_draws_the_legend(tmp_path):
    path = tmp_path / 'legend.png'
    subprocess.run([sys.executable, str(ROOT / 'docs' / 'tools' / 'render_legend.py'), '--output', str(path)],
                   env={**os.environ, 'SDL_VIDEODRIVER': 'dummy',     # this checkout's mate, not an installed one
                        'PYTHONPATH': os.pathsep.join([str(ROOT), os.environ.get('PYTHONPATH', '')])},
                   capture_output=True, text=True, check=True)
    legend = load_png(path)
    assert legend.shape[1] == 800 and legend.shape[0] > 600

    def shows(color) -> bool:
        return bool((np.abs(legend.astype(int) - np.asarray(color)).max(axis=2) <= 2).sum() > 30)

    assert shows(YELLOW) and shows(RUST) and shows(BLUE) and shows(OBSTACLE_GREY.round())
    assert shows(np.round(WAREHOUSE_COLORS[1] * 255)) and shows((51, 153, 51))     # red cargo, green no-cargo target
    assert shows((140, 0, 191))                                                     # a reply arrow (purple)
    assert (legend.max(axis=2) < 60).sum() > 2000                                   # caption text
    docs = (ROOT / 'docs' / 'rendering.md').read_text()
    assert 'images/legend.png' in docs and (ROOT / 'docs' / 'images' / 'legend.png').is_file()
