"""Writing rendered frames to files: animated GIF (Pillow) and video such as MP4 (imageio + ffmpeg).

    frames = []
    env = mate.make('MATE-4v8-9-v0', render_mode='rgb_array')
    env.reset(seed=0)
    for _ in range(100):
        env.step(env.action_space.sample())
        frames.append(env.render())
    save_gif(frames, 'episode.gif', fps=20)
    save_video(frames, 'episode.mp4', fps=30)   # needs imageio-ffmpeg

Frames are (H, W, 3) uint8 RGB arrays (top row first), all of one size, e.g. `env.render()`
in 'rgb_array' mode. Pillow and imageio are imported only when a writer is called.
"""

from __future__ import annotations

import importlib.util
import itertools
import os
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

__all__ = ['VIDEO_SUFFIXES', 'save_gif', 'save_video']

VIDEO_SUFFIXES = ('.mp4', '.m4v', '.mov', '.mkv', '.avi', '.webm')
"""File suffixes `save_video` writes with ffmpeg (`.gif` goes to `save_gif`)."""


def _check_path(path, suffixes: tuple[str, ...], what: str) -> Path:
    try:
        path = Path(os.fspath(path)).expanduser()
    except TypeError:
        raise TypeError(f'{what} path must be a str or os.PathLike, got {type(path).__name__}') from None
    if path.suffix.lower() not in suffixes:
        raise ValueError(f'{what} path {str(path)!r} must end with one of {", ".join(suffixes)}')
    if path.is_dir():
        raise IsADirectoryError(f'{what} path {str(path)!r} is a directory; give a file name')
    parent = path.parent
    if not parent.is_dir():
        raise FileNotFoundError(f'cannot write {str(path)!r}: directory {str(parent)!r} does not exist')
    if not os.access(parent, os.W_OK):
        raise PermissionError(f'cannot write {str(path)!r}: directory {str(parent)!r} is not writable')
    return path


def _check_fps(fps: float) -> float:
    try:
        fps = float(fps)
    except (TypeError, ValueError):
        raise TypeError(f'fps must be a number, got {fps!r}') from None
    if not np.isfinite(fps) or fps <= 0:
        raise ValueError(f'fps must be a positive number, got {fps}')
    return fps


def _frames(frames: Iterable) -> Iterator[np.ndarray]:
    """Validate frames lazily: (H, W, 3) uint8, all the same shape, at least one."""
    if frames is None:
        raise TypeError('frames must be an iterable of (H, W, 3) uint8 arrays, got None')
    if isinstance(frames, np.ndarray) and frames.ndim == 3:
        raise ValueError(f'frames is a single frame of shape {frames.shape}; pass a list of frames '
                         '(or a (T, H, W, 3) array)')
    shape = None
    for index, frame in enumerate(frames):
        frame = np.asarray(frame)
        if frame.ndim != 3 or frame.shape[2] != 3:
            raise ValueError(f'frame {index} has shape {frame.shape}; expected (H, W, 3) RGB')
        if frame.dtype != np.uint8:
            raise TypeError(f'frame {index} has dtype {frame.dtype}; expected uint8 '
                            "(as returned by env.render() with render_mode='rgb_array')")
        if shape is None:
            shape = frame.shape
        elif frame.shape != shape:
            raise ValueError(f'frame {index} has shape {frame.shape}, but frame 0 has {shape}; '
                             'all frames must have the same size')
        yield frame
    if shape is None:
        raise ValueError('no frames to write: the frame list is empty')


def save_gif(frames: Iterable[np.ndarray], path: str | os.PathLike, fps: float = 30.0, loop: int = 0) -> Path:
    """Write frames as an animated GIF with Pillow; returns the path.

    fps: frames per second. GIF stores delays in hundredths of a second, so the effective
    rate is 100 / round(100 / fps) (and many viewers slow down delays under 0.02 s: use
    fps <= 50). loop: number of repetitions, 0 = forever. All frames share one palette (`_paletted`).
    """
    path = _check_path(path, ('.gif',), 'GIF')
    fps = _check_fps(fps)
    try:
        from PIL import Image  # noqa: F401  (used by _paletted; a missing Pillow fails here with this message)
    except ImportError as exc:
        raise ImportError("save_gif needs Pillow: pip install 'mate[render]' (or pip install pillow)") from exc
    images = _paletted(list(_frames(frames)))
    duration = max(10, round(100.0 / fps) * 10)  # milliseconds, a multiple of 10
    # optimize: each palette cut to the colours used (fewer bits per pixel): rendered frames give GIFs half as big
    images[0].save(path, format='GIF', save_all=True, append_images=images[1:], duration=duration, loop=loop,
                   optimize=True, disposal=1)
    return path


PALETTE_SAMPLES = 8
"""Frames, evenly spaced, whose colours make a GIF's shared palette when all frames hold more than 256 colours."""


def _paletted(frames: list[np.ndarray]) -> list:
    """The frames (H, W, 3) uint8 as Pillow 'P' images sharing one palette: exactly the colours the frames hold
    when there are at most 256 (rendered frames hold a hundred or so), each pixel its own colour's index;
    otherwise a median cut over a stack of `PALETTE_SAMPLES` evenly spaced frames, each pixel its nearest colour.
    ~5 ms a 600 px frame, where Pillow's own per-frame quantisation took ~30-50 ms."""
    from PIL import Image

    packed = [_packed(frame) for frame in frames]
    colours = np.unique(np.concatenate([np.unique(p if i == 0 else p[p != packed[i - 1]])
                                        for i, p in enumerate(packed)]))     # only changed pixels after the first
    if len(colours) <= 256:
        rgb = np.stack([(colours >> 16) & 255, (colours >> 8) & 255, colours & 255], axis=-1).astype(np.uint8)
        images = []
        for p in packed:
            image = Image.fromarray(np.searchsorted(colours, p).astype(np.uint8))    # 'L', made 'P' by its palette
            image.putpalette(rgb.ravel().tolist())
            images.append(image)
        return images
    images = [Image.fromarray(frame) for frame in frames]
    picks = sorted({round(i * (len(images) - 1) / max(1, PALETTE_SAMPLES - 1)) for i in range(PALETTE_SAMPLES)})
    width, height = images[0].size
    stack = Image.new('RGB', (width, height * len(picks)))
    for row, index in enumerate(picks):
        stack.paste(images[index], (0, row * height))
    palette = stack.quantize(colors=256, method=Image.Quantize.MEDIANCUT)
    return [image.quantize(palette=palette, dither=Image.Dither.NONE) for image in images]


def _packed(frame: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 -> (H, W) uint32 0xRRGGBB."""
    return (frame[..., 0].astype(np.uint32) << 16) | (frame[..., 1].astype(np.uint32) << 8) | frame[..., 2]


def save_video(frames: Iterable[np.ndarray], path: str | os.PathLike, fps: float = 30.0,
               quality: float | None = 7.0) -> Path:
    """Write frames as a video (MP4 etc. with imageio's ffmpeg backend, H.264) or as a GIF
    (when `path` ends with .gif); returns the path. Frames may be a generator (streamed).

    quality: imageio-ffmpeg quality 0..10 (None = ffmpeg's default bit rate). MP4 needs the
    `imageio-ffmpeg` package (it bundles an ffmpeg binary); without it a clear ImportError
    suggests `pip install imageio-ffmpeg` or saving a .gif instead.
    """
    if isinstance(path, (str, os.PathLike)) and Path(os.fspath(path)).suffix.lower() == '.gif':
        return save_gif(frames, path, fps)
    path = _check_path(path, VIDEO_SUFFIXES + ('.gif',), 'video')
    fps = _check_fps(fps)
    stream = _frames(frames)
    first = next(stream)  # raises on an empty frame list before any file is created
    if importlib.util.find_spec('imageio') is None or importlib.util.find_spec('imageio_ffmpeg') is None:
        raise ImportError(f'writing {path.suffix} videos needs imageio and imageio-ffmpeg: '
                          "pip install imageio imageio-ffmpeg (or 'mate[render]'), or save a .gif "
                          'instead (save_gif / a path ending with .gif)')
    import imageio.v2 as imageio

    writer = imageio.get_writer(path, format='FFMPEG', mode='I', fps=fps, codec='libx264', quality=quality,
                                pixelformat='yuv420p', macro_block_size=2)
    try:
        for frame in itertools.chain([first], stream):
            writer.append_data(frame)
    except BaseException:
        writer.close()
        path.unlink(missing_ok=True)
        raise
    writer.close()
    return path
