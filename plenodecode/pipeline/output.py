"""Step 5 of the workflow: writing a product (display encoding, bit depth, names, atomic rename).

Part of :mod:`plenodecode.pipeline` (see its docstring for the five steps).
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
from pathlib import Path
from typing import Any, Iterator, Sequence

from ..types import LightField
from .inputs import LINEAR_COLOURS, Progress
from .products import Rendered

log = logging.getLogger(__name__)


def display_encoding(colour: str, bit_depth: int) -> bool:
    """Whether an image of colour state ``colour`` gets the sRGB transfer function when written at
    ``bit_depth``: linear states ('camera', 'linear-srgb') do, except 32-bit float outputs."""
    return colour in LINEAR_COLOURS and int(bit_depth) != 32


def stores_display_encoded(format: str, colour: str, bit_depth: int) -> bool:
    """Whether a light field saved as ``format`` at ``bit_depth`` is sRGB-encoded: the rule
    :func:`plenodecode.io.lightfield.save_lightfield` applies by default (8-bit views and ESLF of linear light)."""
    from ..io.lightfield import stores_display_encoded as rule

    return rule(format, colour, bit_depth)


def default_extension(bit_depth: int) -> str:
    """Image type of a product written without an explicit one: 'exr' for 32-bit float, else 'png'."""
    return "exr" if int(bit_depth) == 32 else "png"


#: ``exposure`` of :func:`write_product` that scales an image product so that the 99.5th percentile of its
#: brightest channel (:func:`image_level`) reaches full scale.
AUTO_EXPOSURE = "auto"
#: Limits of ``exposure`` in stops (EV), typed or found by :data:`AUTO_EXPOSURE`: 2^-10 .. 2^10.
MAX_EXPOSURE_EV = 10.0
#: A photograph whose :func:`image_level` is below this is dark: the CLI says so and names ``--exposure``.
DARK_LEVEL = 0.25


def _linear(image: Any, colour: str) -> Any:
    """``image`` in light proportional to the scene's: as it is for linear colour states, else sRGB-decoded."""
    from ..io.images import srgb_decode

    return image if colour in LINEAR_COLOURS else srgb_decode(image)


def image_level(rendered: Rendered) -> float:
    """The 99.5th percentile of the brightest channel of a product's middle image (the centre view of a views
    folder, the middle slice of a focal stack), in linear light of full scale 1: how bright it will look."""
    import numpy as np

    if not rendered.images:
        return 0.0
    _, image = rendered.images[len(rendered.images) // 2]
    lin = np.asarray(_linear(np.nan_to_num(np.asarray(image, np.float32)), rendered.colour))
    brightest = lin.max(axis=-1) if lin.ndim == 3 else lin
    return float(np.percentile(brightest, 99.5))


def dark_note(level: float, what: str = "the picture") -> str | None:
    """What the command line and a batch's index page say of a picture whose :func:`image_level` is ``level``
    at the default exposure, when below :data:`DARK_LEVEL`: that ``what`` is dark and how ``--exposure`` brightens
    it; None when it is not dark."""
    if level >= DARK_LEVEL:
        return None
    return (f"{what} is dark (its brightest 0.5 % reach {100 * level:.0f} % of full scale, in linear light); "
            "--exposure auto brightens it to full scale, --exposure 2 by two stops")


def check_exposure(exposure: float | str) -> float | str:
    """``exposure`` as :func:`exposure_gain` takes it: 'auto', or a float of stops within +-MAX_EXPOSURE_EV.

    Raises
    ------
    ValueError
        Anything else.
    """
    if isinstance(exposure, str) and exposure.strip().lower() == AUTO_EXPOSURE:
        return AUTO_EXPOSURE
    try:
        ev = float(exposure)
    except (TypeError, ValueError):
        ev = math.nan
    if not abs(ev) <= MAX_EXPOSURE_EV:
        raise ValueError(f"exposure must be {AUTO_EXPOSURE!r} or stops within +-{MAX_EXPOSURE_EV:g}, got {exposure!r}")
    return ev


def exposure_gain(rendered: Rendered, exposure: float | str = 0.0) -> float:
    """The factor on the linear light of a product's images: ``2 ** exposure`` (stops), or for
    :data:`AUTO_EXPOSURE` ``1 / image_level`` (within +-:data:`MAX_EXPOSURE_EV` stops; 1 for a black image).

    Raises
    ------
    ValueError
        ``exposure`` is neither 'auto' nor a number of stops within +-MAX_EXPOSURE_EV (:func:`check_exposure`).
    """
    exposure = check_exposure(exposure)
    if exposure == AUTO_EXPOSURE:
        level = image_level(rendered)
        if not level > 0:
            return 1.0
        exposure = min(MAX_EXPOSURE_EV, max(-MAX_EXPOSURE_EV, -math.log2(level)))
    return float(2.0 ** exposure)


def expose(image: Any, colour: str, gain: float) -> Any:
    """``image`` with its linear light times ``gain`` (sRGB-decoded and re-encoded for an sRGB-encoded state,
    'srgb' or 'camera-srgb-curve')."""
    if gain == 1.0:
        return image
    from ..io.images import srgb_encode

    scaled = _linear(image, colour) * image.dtype.type(gain)
    return scaled if colour in LINEAR_COLOURS else srgb_encode(scaled)


def write_image_file(path: str | os.PathLike, image: Any, *, colour: str, bit_depth: int,
                     overwrite: bool = False, gain: float = 1.0) -> Path:
    """Write one rendered image (:func:`plenodecode.io.images.write_image`, atomic) with :func:`display_encoding`,
    its linear light times ``gain`` first (:func:`expose`).

    Raises
    ------
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    ValueError
        A bit depth the image type cannot hold.
    """
    from ..io import images

    return images.write_image(path, expose(image, colour, gain), bit_depth=int(bit_depth), overwrite=overwrite,
                              encode_srgb=display_encoding(colour, bit_depth), colour=colour)


def refuse_folder_clash(folder: str | os.PathLike, names: Sequence[str], overwrite: bool) -> None:
    """Check a folder output before any work: ``folder`` is a folder (or absent) and, unless ``overwrite``,
    none of ``names`` exists in it.  Creates nothing.

    Raises
    ------
    FileExistsError
        A clash.
    NotADirectoryError
        ``folder`` is a file (even with ``overwrite``).
    """
    from ..io.atomic import refuse_existing

    p = Path(folder)
    if p.exists() and not p.is_dir():       # not even with overwrite: a folder output never replaces a file
        raise NotADirectoryError(f"{p} is a file; this output is a folder: name a folder that is not a file")
    if p.is_dir():
        refuse_existing([p / n for n in names], overwrite)


@contextlib.contextmanager
def staged_folder(folder: str | os.PathLike, names: Sequence[str], *, overwrite: bool = False) -> Iterator[Path]:
    """Context manager for the files ``names`` of a folder output: write them into the yielded staging folder;
    they appear under ``folder`` together on normal exit, and on an exception nothing is left.

    A missing ``folder`` is staged whole and renamed into place (so a failed run leaves no empty folder); into
    an existing one the files are renamed one by one, other files in it are kept.

    Raises
    ------
    FileExistsError
        See :func:`refuse_folder_clash` (checked on entry, before anything is created).
    """
    from ..io.atomic import atomic_output, commit, discard, temporary_sibling

    p = Path(folder)
    refuse_folder_clash(p, names, overwrite)
    if not p.exists():
        with atomic_output(p, folder=True) as tmp:
            yield tmp
        return
    stage = temporary_sibling(p / "staging", folder=True)
    created: list[Path] = []
    try:
        yield stage
        refuse_folder_clash(p, names, overwrite)
        for name in names:
            existed = os.path.lexists(p / name)
            commit(stage / name, p / name)
            if not existed:
                created.append(p / name)
    except BaseException:
        for f in created:      # a rename failed half-way: do not leave an incomplete set behind
            discard(f)
        raise
    finally:
        discard(stage)


def write_product(rendered: Rendered, output: str | os.PathLike, *, bit_depth: int = 16, ext: str | None = None,
                  overwrite: bool = False, exposure: float | str = 0.0, progress: Progress = None) -> list[Path]:
    """Write the images and documents of a product: one image file ``output``, or the folder ``output``.

    Parameters
    ----------
    rendered : Rendered
        An image product (not 'depth': :func:`write_depth`).
    output : path-like
        The image file (its extension gives the type), or the folder of a folder product.
    bit_depth : {8, 16, 32}
    ext : str, optional
        Image type of a folder product's files (default :func:`default_extension`).
    overwrite : bool
    exposure : float or 'auto'
        Stops (EV) the images' linear light is scaled by, the same for every image of a folder; 'auto': so that
        the middle image's brightest 0.5 % reach full scale (:func:`exposure_gain`).  0 = as rendered.
    progress : callable(done, total), optional
        After every image of a folder product.

    Returns
    -------
    list of Path
        The written file, or the folder's files.
    """
    out = Path(output)
    gain = exposure_gain(rendered, exposure)
    if not rendered.folder:
        (_, image), = rendered.images
        return [write_image_file(out, image, colour=rendered.colour, bit_depth=bit_depth, overwrite=overwrite,
                                 gain=gain)]
    from ..io.atomic import write_text_atomic

    ext = ext or default_extension(bit_depth)
    names = rendered.file_names(ext)
    with staged_folder(out, names, overwrite=overwrite) as stage:
        for i, (name, (_, image)) in enumerate(zip(names, rendered.images)):
            write_image_file(stage / name, image, colour=rendered.colour, bit_depth=bit_depth, gain=gain)
            if progress is not None:
                progress(i + 1, len(rendered.images))
        for name, document in rendered.documents:
            write_text_atomic(stage / name, json.dumps(document(ext), indent=1))
    return [out / n for n in names]


def write_parallax(rendered: Rendered, animation: str | os.PathLike, *, fps: float,
                   frames_dir: str | os.PathLike | None = None, bit_depth: int = 16,
                   overwrite: bool = False, exposure: float | str = 0.0) -> list[Path]:
    """Write a parallax product: the animation (.gif / .webp) and, with ``frames_dir``, its numbered frames
    (``frame_000.png`` ...).  Both or neither: the frames folder is committed after the animation is written.
    ``exposure``: as :func:`write_product`, one gain for the animation and the frames."""
    from ..io import images

    gain = exposure_gain(rendered, exposure)

    def write_animation() -> Path:
        frames = expose(rendered.data["animation"], rendered.colour, gain)
        return images.write_animation(animation, frames, fps=fps, overwrite=overwrite,
                                      encode_srgb=rendered.colour in LINEAR_COLOURS)

    if frames_dir is None:
        return [write_animation()]
    names = rendered.file_names("png")
    with staged_folder(frames_dir, names, overwrite=overwrite) as stage:
        for name, (_, frame) in zip(names, rendered.images):
            write_image_file(stage / name, frame, colour=rendered.colour, bit_depth=bit_depth, gain=gain)
        written = [write_animation()]
    return written + [Path(frames_dir) / n for n in names]


def write_depth(rendered: Rendered, pfm_path: str | os.PathLike, *, ply: str | os.PathLike | None = None,
                title: str | None = None, full: bool = True, min_confidence: float | None = None,
                overwrite: bool = False) -> list[Path]:
    """Write a depth product: ``X.pfm`` (the values, float32), and with ``full`` ``X.exr``, a colour-mapped
    ``X.png`` whose pixels of confidence below ``min_confidence`` are grey (default
    :data:`plenodecode.io.depthio.DEFAULT_MIN_CONFIDENCE`) and the confidence map ``X_confidence.exr`` /
    ``X_confidence.png`` (:func:`plenodecode.io.depthio.write_depth_outputs`), plus a PLY point cloud with
    ``ply`` (with ``full=False`` too: the PFM and the PLY)."""
    from ..io.depthio import DEFAULT_MIN_CONFIDENCE, check_min_confidence

    min_confidence = check_min_confidence(DEFAULT_MIN_CONFIDENCE if min_confidence is None else min_confidence)
    values = rendered.data["values"]
    if not full:
        from ..io.depthio import depth_output_paths, write_point_cloud
        from ..io.pfm import write_pfm

        if ply is not None and rendered.data.get("points") is None:
            raise ValueError("ply needs points (3-D coordinates of every pixel): render the depth with points=True")
        return [write_pfm(depth_output_paths(pfm_path)["pfm"], values, overwrite=overwrite)] + (
            [] if ply is None else [write_point_cloud(ply, rendered.data["points"], rendered.data.get("colours"),
                                                      overwrite=overwrite)])
    from ..io.depthio import write_depth_outputs

    return write_depth_outputs(pfm_path, values, label=rendered.data["label"],
                               confidence=rendered.data["depthmap"].confidence, min_confidence=min_confidence,
                               points=rendered.data.get("points"), colours=rendered.data.get("colours"), ply=ply,
                               title=title, near=rendered.data.get("near"), overwrite=overwrite)


def write_lightfield(lf: LightField, path: str | os.PathLike, *, format: str | None = None, bit_depth: int = 16,
                     display: bool | None = None, overwrite: bool = False, progress: Progress = None) -> Path:
    """Save a light field (:func:`plenodecode.io.lightfield.save_lightfield`, atomic).

    ``display=True`` applies :func:`display_encoding` (for image formats meant for viewing, e.g. the views of a
    batch), False stores the data as they are (linear); the default is save_lightfield's,
    :func:`stores_display_encoded` (8-bit views and ESLF encoded).
    """
    from ..io.lightfield import save_lightfield

    encode = None if display is None else display and display_encoding(lf.colour, bit_depth)
    return Path(save_lightfield(lf, path, format=format, bit_depth=int(bit_depth), overwrite=overwrite,
                                progress=progress, encode_srgb=encode))
