"""Showing what the robots do: frames, mosaics, a window, GIF/MP4 files.

Frames are drawn by the Rust core in software (``_core.Batch.render``, tiny-skia): no display and
no OpenGL are needed, so ``render_mode="rgb_array"`` works on a headless machine. This module adds
what is easier in Python: tiling the frames of several worlds into one mosaic, a pygame window for
``render_mode="human"`` (imported lazily: ``pip install khepera-gym[render]``), and writing a list
of frames to a GIF (Pillow, which matplotlib already installs) or an MP4 (imageio-ffmpeg, in the
``render`` extra).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from khepera_gym._inputs import check_int
from khepera_gym.errors import ConfigError, KheperaError

#: Default frame size (pixels, width and height) of an arena up to 4 m a side.
DEFAULT_FRAME_SIZE = (480, 480)
#: Smallest and largest frame side (pixels): a 4096 x 4096 frame is 48 MiB.
FRAME_SIDES = (16, 4096)
#: Pixels per metre of a larger arena's default frame (480 px for 4 m), so that its robots
#: stay visible: a 20 m swarm arena gets 1280 px, a robot about 9 px across.
PIXELS_PER_METRE = 120
#: Largest side (pixels) of a default frame.
MAX_DEFAULT_FRAME = 1280
#: Robot positions kept for the fading trails drawn in frames.
TRAIL_LENGTH = 100

Frame = npt.NDArray[np.uint8]


def check_frame_size(frame_size: Sequence[int]) -> tuple[int, int]:
    """Validates a (width, height) pair in pixels.

    Raises:
        ConfigError: Not two ints in 16..4096.
    """
    if isinstance(frame_size, (str, bytes)) or not isinstance(frame_size, (Sequence, np.ndarray)):
        raise ConfigError(f"frame_size must be (width, height), got {frame_size!r}")
    if len(frame_size) != 2:
        raise ConfigError(f"frame_size must be (width, height), got {len(frame_size)} values")
    low, high = FRAME_SIDES
    width, height = (
        check_int(v, f"frame_size {side}", low, high)
        for v, side in zip(frame_size, ("width", "height"), strict=True)
    )
    return width, height


def default_frame_size(arena: Sequence[float]) -> tuple[int, int]:
    """The default (width, height) of a frame of an arena of ``arena`` = (width, height) m:
    :data:`DEFAULT_FRAME_SIZE`, or for an arena wider than 4 m, :data:`PIXELS_PER_METRE` of
    its larger side, at most :data:`MAX_DEFAULT_FRAME` pixels (square)."""
    side = math.ceil(PIXELS_PER_METRE * max(float(v) for v in arena))
    side = min(max(side, DEFAULT_FRAME_SIZE[0]), MAX_DEFAULT_FRAME)
    return side, side


def check_view(
    zoom: float, center: Sequence[float] | None
) -> tuple[float, tuple[float, float] | None]:
    """Validates a frame's view: ``zoom`` >= 1 (1: the whole arena) about ``center`` (x, y in
    m; None: the arena's centre).

    Raises:
        ConfigError: A zoom below 1 or not finite, or a center that is not two finite numbers.
    """
    try:
        zoom = float(zoom)
    except (TypeError, ValueError) as error:
        raise ConfigError(f"zoom must be a number >= 1, got {zoom!r}") from error
    if not (math.isfinite(zoom) and 1.0 <= zoom <= 1000.0):
        raise ConfigError(f"zoom must be in [1, 1000] (1: the whole arena), got {zoom}")
    if center is None:
        return zoom, None
    try:
        x, y = (float(v) for v in center)
    except (TypeError, ValueError) as error:
        raise ConfigError(f"center must be (x, y) in metres, got {center!r}") from error
    if not (math.isfinite(x) and math.isfinite(y)):
        raise ConfigError(f"center must be finite, got {center!r}")
    return zoom, (x, y)


def mosaic(frames: Sequence[Frame], columns: int | None = None, gap: int = 4) -> Frame:
    """Tiles equally sized frames into one image, row by row, with a dark gap between tiles.

    Args:
        frames: (H, W, 3) uint8 frames.
        columns: Tiles per row; default the smallest square grid.
        gap: Pixels between tiles.

    Returns:
        One (rows·H + gaps, columns·W + gaps, 3) uint8 frame.
    """
    if not frames:
        raise KheperaError("mosaic() needs at least one frame")
    count = len(frames)
    columns = columns or math.ceil(math.sqrt(count))
    rows = math.ceil(count / columns)
    height, width, _ = frames[0].shape
    out = np.full(
        (rows * height + (rows - 1) * gap, columns * width + (columns - 1) * gap, 3),
        40,
        dtype=np.uint8,
    )
    for index, frame in enumerate(frames):
        row, column = divmod(index, columns)
        top, left = row * (height + gap), column * (width + gap)
        out[top : top + height, left : left + width] = frame
    return out


class HumanWindow:
    """A pygame window showing frames at ``fps``; closing it never crashes the program.

    After the user closes the window, :meth:`show` does nothing and :attr:`closed` is True.
    """

    def __init__(self, title: str, fps: int) -> None:
        try:
            import pygame
        except ImportError as error:
            raise KheperaError(
                'render_mode="human" needs pygame: pip install "khepera-gym[render]"'
            ) from error
        self._pygame = pygame
        self._title = title
        self._fps = fps
        self._screen: Any = None
        self._clock: Any = None
        self.closed = False

    def show(self, frame: Frame) -> None:
        """Shows one frame and waits to keep ``fps``; handles the window's events."""
        if self.closed:
            return
        pygame = self._pygame
        if self._screen is None:
            pygame.init()
            pygame.display.set_caption(self._title)
            self._screen = pygame.display.set_mode((frame.shape[1], frame.shape[0]))
            self._clock = pygame.time.Clock()
        for event in pygame.event.get():
            if event.type == pygame.QUIT:
                self.close()
                return
        surface = pygame.surfarray.make_surface(np.ascontiguousarray(frame.swapaxes(0, 1)))
        self._screen.blit(surface, (0, 0))
        pygame.display.flip()
        self._clock.tick(self._fps)

    def close(self) -> None:
        """Closes the window (safe to call twice)."""
        if self._screen is not None:
            self._pygame.display.quit()
            self._screen = None
        self.closed = True


#: The video formats :func:`save_video` writes, by the file's suffix.
VIDEO_SUFFIXES = (".gif", ".mp4")


def check_video(path: str | Path, fps: int = 20) -> None:
    """Checks, before any frame is drawn, that :func:`save_video` can write ``path``: a known
    format, a frame rate >= 1, and for MP4 its writer installed.

    Raises:
        ConfigError: An unknown suffix or a frame rate below 1.
        KheperaError: imageio-ffmpeg missing for MP4 (the message names the extra).
    """
    suffix = Path(path).suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        raise ConfigError(f"unknown video format {suffix!r} of {path}: use .gif or .mp4")
    if not (isinstance(fps, int) and fps >= 1):
        raise ConfigError(f"fps must be an integer >= 1, got {fps!r}")
    if suffix == ".mp4":
        try:
            import imageio.v2  # noqa: F401
            import imageio_ffmpeg  # noqa: F401
        except ImportError as error:
            raise KheperaError(
                'MP4 output needs imageio and imageio-ffmpeg: pip install "khepera-gym[render]" '
                "(or write a .gif)"
            ) from error


def _video_frames(frames: Sequence[npt.ArrayLike | None]) -> list[Frame]:
    """``frames`` as (height, width, 3) uint8 arrays of one size.

    Raises:
        KheperaError: No frames, a None (an env made without ``render_mode="rgb_array"``
            renders None), or a frame that is not (height, width, 3) or not the first's size.
    """
    if len(frames) == 0:
        raise KheperaError("save_video() got no frames")
    checked = []
    for index, frame in enumerate(frames):
        if frame is None:
            raise KheperaError(
                f"save_video(): frame {index} is None; make the env with "
                'render_mode="rgb_array" for render() to return frames'
            )
        array = np.asarray(frame)
        if array.ndim != 3 or array.shape[2] != 3:
            raise KheperaError(
                f"save_video(): frame {index} has shape {array.shape}, not (height, width, 3)"
            )
        if checked and array.shape != checked[0].shape:
            raise KheperaError(
                f"save_video(): frame {index} is {array.shape}, frame 0 {checked[0].shape}"
            )
        checked.append(array.astype(np.uint8, copy=False))
    return checked


def save_video(frames: Sequence[npt.ArrayLike | None], path: str | Path, fps: int = 20) -> Path:
    """Writes frames to ``path``: ``.gif`` with Pillow, ``.mp4`` with imageio-ffmpeg.

    Args:
        frames: (height, width, 3) uint8 frames of one size, as ``env.render()`` returns with
            ``render_mode="rgb_array"`` (Gymnasium types its result as optional: a None here
            is an error).
        path: The file to write.
        fps: Frames per second.

    Raises:
        ConfigError: An unknown suffix, or a frame rate below 1.
        KheperaError: No frames, a None or misshapen frame, or imageio-ffmpeg missing for MP4.
    """
    path = Path(path)
    check_video(path, fps)
    frames = _video_frames(frames)
    suffix = path.suffix.lower()
    if suffix == ".gif":
        from PIL import Image

        images = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in frames]
        images[0].save(
            path,
            save_all=True,
            append_images=images[1:],
            duration=max(1, round(1000 / fps)),
            loop=0,
            optimize=False,
        )
        return path
    if suffix == ".mp4":
        try:
            import imageio.v2 as imageio
        except ImportError as error:
            raise KheperaError(
                'MP4 output needs imageio and imageio-ffmpeg: pip install "khepera-gym[render]" '
                "(or write a .gif)"
            ) from error
        with imageio.get_writer(path, fps=fps, codec="libx264", macro_block_size=8) as writer:
            for frame in frames:
                writer.append_data(np.asarray(frame, dtype=np.uint8))
        return path
    raise AssertionError(f"check_video let {suffix!r} through")  # pragma: no cover


__all__ = [
    "DEFAULT_FRAME_SIZE",
    "FRAME_SIDES",
    "MAX_DEFAULT_FRAME",
    "PIXELS_PER_METRE",
    "TRAIL_LENGTH",
    "VIDEO_SUFFIXES",
    "HumanWindow",
    "check_frame_size",
    "check_video",
    "check_view",
    "default_frame_size",
    "mosaic",
    "save_video",
]


class Renderer:
    """The rendering side of an env over a ``_core.Batch``: frames of its worlds, the window.

    Args:
        batch: The env's batch.
        render_mode: None, "rgb_array" or "human".
        frame_size: (width, height) of one world's frame in pixels; None: from the arena's size
            (:func:`default_frame_size`).
        fps: Frames per second of the "human" window.
        title: The window's title.
        zoom: Magnification (1: the whole arena); see :meth:`set_view`.
        center: The world point (x, y in m) at the frame's centre; None: the arena's centre.
    """

    MODES = ("rgb_array", "human")

    def __init__(
        self,
        batch: Any,
        render_mode: str | None,
        frame_size: Sequence[int] | None = None,
        fps: int = 20,
        title: str = "khepera_gym",
        zoom: float = 1.0,
        center: Sequence[float] | None = None,
    ) -> None:
        if render_mode is not None and render_mode not in self.MODES:
            raise ConfigError(
                f"render_mode must be None, 'rgb_array' or 'human', got {render_mode!r}"
            )
        self.render_mode = render_mode
        if frame_size is None:
            frame_size = default_frame_size(batch.scene(0)["arena"])
        self.width, self.height = check_frame_size(frame_size)
        self.zoom, self.center = check_view(zoom, center)
        self._batch = batch
        self._fps = fps
        self._title = title
        self._window: HumanWindow | None = None
        if render_mode is not None:
            batch.set_trail_length(TRAIL_LENGTH)

    def set_view(self, zoom: float = 1.0, center: Sequence[float] | None = None) -> None:
        """Which part of the world the frames show: ``zoom`` times magnified (1: the whole
        arena, 4: a quarter of its width) about ``center`` (x, y in m; None: the arena's centre).

        Raises:
            ConfigError: A zoom below 1, or a center that is not two finite numbers.
        """
        self.zoom, self.center = check_view(zoom, center)

    def frame(self, index: int = 0) -> Frame:
        """World ``index``'s frame, (height, width, 3) uint8."""
        if self.zoom == 1.0 and self.center is None:
            return self._batch.render(index, self.width, self.height)
        return self._batch.render(index, self.width, self.height, self.zoom, self.center)

    def frames(self, count: int) -> Frame:
        """A mosaic of the first ``count`` worlds' frames."""
        count = max(1, min(count, self._batch.num_worlds))
        return mosaic([self.frame(i) for i in range(count)])

    def render(self, count: int = 1) -> Frame | None:
        """What ``env.render()`` returns: the frame (mosaic of ``count`` worlds) for
        "rgb_array", None after showing it for "human", None without a render mode."""
        if self.render_mode is None:
            return None
        image = self.frame() if count == 1 else self.frames(count)
        if self.render_mode == "rgb_array":
            return image
        if self._window is None:
            self._window = HumanWindow(self._title, self._fps)
        self._window.show(image)
        return None

    def __getstate__(self) -> dict[str, Any]:
        # A pickled env reopens its window at the next render, in the process that unpickles it.
        return {**self.__dict__, "_window": None}

    def close(self) -> None:
        """Closes the window, if any."""
        if self._window is not None:
            self._window.close()
            self._window = None


__all__ += ["Renderer"]
