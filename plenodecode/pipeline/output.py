"""Step 5 of the workflow: writing a product (display encoding, bit depth, names, atomic rename).

Part of :mod:`plenodecode.pipeline` (see its docstring for the five steps).
"""

from __future__ import annotations

import contextlib
import json
import logging
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


def default_extension(bit_depth: int) -> str:
    """Image type of a product written without an explicit one: 'exr' for 32-bit float, else 'png'."""
    return "exr" if int(bit_depth) == 32 else "png"


def write_image_file(path: str | os.PathLike, image: Any, *, colour: str, bit_depth: int,
                     overwrite: bool = False) -> Path:
    """Write one rendered image (:func:`plenodecode.io.images.write_image`, atomic) with :func:`display_encoding`.

    Raises
    ------
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    ValueError
        A bit depth the image type cannot hold.
    """
    from ..io import images

    return images.write_image(path, image, bit_depth=int(bit_depth), overwrite=overwrite,
                              encode_srgb=display_encoding(colour, bit_depth))


def refuse_folder_clash(folder: str | os.PathLike, names: Sequence[str], overwrite: bool) -> None:
    """Check a folder output before any work: ``folder`` is a folder (or absent) and, unless ``overwrite``,
    none of ``names`` exists in it.  Creates nothing.

    Raises
    ------
    FileExistsError
        A clash; or ``folder`` is a file.
    """
    from ..io.atomic import refuse_existing

    p = Path(folder)
    if p.exists() and not p.is_dir():
        raise FileExistsError(f"{p} exists and is not a folder")
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
                  overwrite: bool = False, progress: Progress = None) -> list[Path]:
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
    progress : callable(done, total), optional
        After every image of a folder product.

    Returns
    -------
    list of Path
        The written file, or the folder's files.
    """
    out = Path(output)
    if not rendered.folder:
        (_, image), = rendered.images
        return [write_image_file(out, image, colour=rendered.colour, bit_depth=bit_depth, overwrite=overwrite)]
    from ..io.atomic import write_text_atomic

    ext = ext or default_extension(bit_depth)
    names = rendered.file_names(ext)
    with staged_folder(out, names, overwrite=overwrite) as stage:
        for i, (name, (_, image)) in enumerate(zip(names, rendered.images)):
            write_image_file(stage / name, image, colour=rendered.colour, bit_depth=bit_depth)
            if progress is not None:
                progress(i + 1, len(rendered.images))
        for name, document in rendered.documents:
            write_text_atomic(stage / name, json.dumps(document(ext), indent=1))
    return [out / n for n in names]


def write_parallax(rendered: Rendered, animation: str | os.PathLike, *, fps: float,
                   frames_dir: str | os.PathLike | None = None, bit_depth: int = 16,
                   overwrite: bool = False) -> list[Path]:
    """Write a parallax product: the animation (.gif / .webp) and, with ``frames_dir``, its numbered frames
    (``frame_000.png`` ...).  Both or neither: the frames folder is committed after the animation is written."""
    from ..io import images

    def write_animation() -> Path:
        return images.write_animation(animation, rendered.data["animation"], fps=fps, overwrite=overwrite,
                                      encode_srgb=rendered.colour in LINEAR_COLOURS)

    if frames_dir is None:
        return [write_animation()]
    names = rendered.file_names("png")
    with staged_folder(frames_dir, names, overwrite=overwrite) as stage:
        for name, (_, frame) in zip(names, rendered.images):
            write_image_file(stage / name, frame, colour=rendered.colour, bit_depth=bit_depth)
        written = [write_animation()]
    return written + [Path(frames_dir) / n for n in names]


def write_depth(rendered: Rendered, pfm_path: str | os.PathLike, *, ply: str | os.PathLike | None = None,
                title: str | None = None, full: bool = True, min_confidence: float | None = None,
                overwrite: bool = False) -> list[Path]:
    """Write a depth product: ``X.pfm`` (the values, float32), and with ``full`` ``X.exr``, a colour-mapped
    ``X.png`` whose pixels of confidence below ``min_confidence`` are grey (default
    :data:`plenodecode.io.depthio.DEFAULT_MIN_CONFIDENCE`) and the confidence map ``X_confidence.exr`` /
    ``X_confidence.png`` (:func:`plenodecode.io.depthio.write_depth_outputs`), plus a PLY point cloud with
    ``ply``."""
    from ..io.depthio import DEFAULT_MIN_CONFIDENCE, check_min_confidence

    min_confidence = check_min_confidence(DEFAULT_MIN_CONFIDENCE if min_confidence is None else min_confidence)
    values = rendered.data["values"]
    if not full:
        from ..io.pfm import write_pfm

        return [write_pfm(pfm_path, values, overwrite=overwrite)]
    from ..io.depthio import write_depth_outputs

    return write_depth_outputs(pfm_path, values, label=rendered.data["label"],
                               confidence=rendered.data["depthmap"].confidence, min_confidence=min_confidence,
                               points=rendered.data.get("points"), colours=rendered.data.get("colours"), ply=ply,
                               title=title, overwrite=overwrite)


def write_lightfield(lf: LightField, path: str | os.PathLike, *, format: str | None = None, bit_depth: int = 16,
                     display: bool = False, overwrite: bool = False, progress: Progress = None) -> Path:
    """Save a light field (:func:`plenodecode.io.lightfield.save_lightfield`, atomic).

    ``display=True`` applies :func:`display_encoding` (for image formats meant for viewing, e.g. the views of a
    batch); otherwise the data are stored as they are (linear).
    """
    from ..io.lightfield import save_lightfield

    return Path(save_lightfield(lf, path, format=format, bit_depth=int(bit_depth), overwrite=overwrite,
                                progress=progress, encode_srgb=display and display_encoding(lf.colour, bit_depth)))
