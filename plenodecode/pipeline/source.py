"""Step 3 of the workflow: an opened input (:class:`Source`), decoded on first use.

Part of :mod:`plenodecode.pipeline` (see its docstring for the five steps).
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
from dataclasses import replace
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Hashable, Mapping

from ..types import LightField, RawCapture
from .inputs import Progress, open_input, quieted, read_dark_frame
from .calibration import Calibration, choose_calibration
from .needs import check_product

if TYPE_CHECKING:
    from ..io.mosaic_levels import MosaicOptions
    from ..optics import MicroscopeOptics
    from ..raymodel import GeometricCalibration

log = logging.getLogger(__name__)


class Source:
    """An opened input, ready for rendering: a light field, or a raw with its calibration.

    A raw is decoded on the first use of :attr:`lightfield` (once); products that render from the raw itself
    (:func:`~plenodecode.pipeline.products.render_total_focus`) never decode it, and share what they render
    alike through :meth:`shared`.

    Parameters
    ----------
    lightfield : LightField, optional
        An input that is already a light field.
    raw : RawCapture, optional
        A raw; needs ``calibration``.
    calibration : Calibration, optional
    decode_options : mapping, optional
        Keywords of :func:`plenodecode.decoding.decode` (``demosaic``, ``colour``, ``n_views``, ``dark``,
        ``hot_pixels``, ``workers``).
    progress : callable(done, total), optional
        Progress of the decoding.
    geometry : GeometricCalibration, optional
        Rectify the light field (:func:`plenodecode.decoding.rectify.rectify`) on first use; its shape is
        checked now (:func:`check_geometry`), before any work.
    """

    def __init__(self, *, lightfield: LightField | None = None, raw: RawCapture | None = None,
                 calibration: Calibration | None = None, decode_options: Mapping[str, Any] | None = None,
                 progress: Progress = None, geometry: GeometricCalibration | None = None) -> None:
        if (lightfield is None) == (raw is None):
            raise ValueError("pass exactly one of lightfield and raw")
        if raw is not None and calibration is None:
            raise ValueError("a raw needs its calibration")
        self.raw = raw
        self.calibration = calibration
        self.decode_options = dict(decode_options or {})
        self.progress = progress
        self.geometry = geometry
        self._input = lightfield
        self._shared: dict[Hashable, Any] = {}
        if geometry is not None:
            check_geometry(geometry, lightfield=lightfield, calibration=calibration,
                           n_views=self.decode_options.get("n_views"))
        elif lightfield is not None:
            self.__dict__["lightfield"] = lightfield

    @cached_property
    def lightfield(self) -> LightField:
        """The light field (V, U, Y, X, C) float32: the input itself, or the raw decoded; rectified with
        :attr:`geometry` when given."""
        if self.raw is None:
            from ..decoding.rectify import rectify

            return rectify(self._input, self.geometry, progress=self.progress)
        return decode_raw(self.raw, self.calibration, progress=self.progress, geometry=self.geometry,
                          **self.decode_options)

    def shared(self, key: Hashable, make: Callable[[], Any]) -> Any:
        """``make()``, computed once per source and ``key``: what several products of one input render alike (a
        focused raw's colour image and total focus, which the photograph and the depth map both use)."""
        if key not in self._shared:
            self._shared[key] = make()
        return self._shared[key]

    @property
    def input(self) -> LightField | RawCapture:
        """The input as read (the raw, or the light field before any rectification): what its metadata says
        without calibrating or decoding (:func:`~plenodecode.pipeline.needs.check_product`)."""
        return self.raw if self.raw is not None else self._input

    @property
    def focused(self) -> bool:
        """True for a focused-plenoptic (Raytrix) raw: a grid with lens types."""
        grid = None if self.raw is None else self.calibration.grid
        return grid is not None and grid.lens_type is not None


def check_geometry(geometry: GeometricCalibration, *, lightfield: LightField | None = None,
                   calibration: Calibration | None = None, n_views: int | None = None) -> None:
    """Refuse a geometric calibration made for light fields of another shape than ``lightfield`` (or one
    already rectified) or than the raw decoded with ``calibration`` and ``n_views`` will have
    (:class:`~plenodecode.errors.GeometryMismatchError`; nothing is decoded)."""
    from ..decoding.rectify import check_shape, decoded_shape
    from ..errors import GeometryMismatchError

    if lightfield is not None:
        if (lightfield.geometry.ray_model or {}).get("rectified"):
            raise GeometryMismatchError("the light field is already rectified (it carries its calibrated ray "
                                        "model); use it without --geometry")
        check_shape(geometry, lightfield.shape, "light field")
    else:
        check_shape(geometry, decoded_shape(calibration.grid, n_views), "decoded light field")


def _channel_progress(progress: Callable[[int, int], None], channel: int, done: int, total: int) -> None:
    """``progress`` of channel ``channel``'s decode as a part of three: ``(channel total + done, 3 total)``."""
    progress(channel * total + done, 3 * total)


def decode_raw(raw: RawCapture, calibration: Calibration, *, progress: Progress = None,
               geometry: GeometricCalibration | None = None, **decode_options: Any) -> LightField:
    """Decode ``raw`` with ``calibration`` (:func:`plenodecode.decoding.decode`; devignetted by its white),
    rectified with ``geometry`` when given (a geometric calibration,
    :func:`plenodecode.decoding.rectify.rectify`).
    A Raytrix RGB export is decoded channel by channel from its linear sRGB values (colour 'linear-srgb').

    Returns
    -------
    LightField
        ``data`` (V, U, Y, X, C) float32.
    """
    from ..decoding import decode
    from ..io.raytrix import is_rgb_export, rgb_export_channels

    log.info("decoding %s", raw.path)
    if not is_rgb_export(raw):
        return decode(raw, calibration.grid, white=calibration.white, progress=progress, geometry=geometry,
                      **decode_options)
    # a Raytrix RGB export (already demosaiced, sRGB): its linear channels decoded one by one, stacked as C = 3
    import numpy as np

    white = calibration.white
    whites = rgb_export_channels(white) if white is not None and is_rgb_export(white) else [white] * 3
    planes = []
    for c, (plane, w) in enumerate(zip(rgb_export_channels(raw), whites)):
        # one progress bar over the three decodes, and the decoder's warnings (the same for every channel) once
        part = None if progress is None else functools.partial(_channel_progress, progress, c)
        with quieted("plenodecode.decoding.decoder") if c > 0 else contextlib.nullcontext():
            planes.append(decode(plane, calibration.grid, white=w, progress=part, **decode_options))
    state = "camera" if decode_options.get("colour") == "camera" else "linear-srgb"
    lf = planes[0].replace(data=np.concatenate([lf.data for lf in planes], axis=-1), colour=state)
    if geometry is None:
        return lf
    from ..decoding.rectify import rectify

    return rectify(lf, geometry, progress=progress)


def open_source(path: str | os.PathLike, *, grid: str | os.PathLike | None = None,
                white: str | os.PathLike | None = None, database: str | os.PathLike | None = None,
                self_calibrate: bool = False, mosaic: MosaicOptions | None = None,
                raytrix_xml: str | os.PathLike | None = None,
                dark: str | os.PathLike | RawCapture | None = None, optics: MicroscopeOptics | None = None,
                decode_options: Mapping[str, Any] | None = None, progress: Progress = None,
                geometry: GeometricCalibration | None = None,
                check: Mapping[str, Mapping[str, Any]] | None = None) -> Source:
    """:func:`open_input`, then for a raw :func:`choose_calibration`; the decoding waits for first use.

    ``check`` (product name -> its options, as :func:`~plenodecode.pipeline.render_product` will take them) is
    checked against the input's metadata as soon as it is read, before the calibration and any decoding
    (:func:`~plenodecode.pipeline.needs.check_product`: alpha, a focus distance or metric depth without the
    camera constants raises :class:`~plenodecode.errors.MissingConstantsError`).

    The calibration, ``mosaic``, ``raytrix_xml`` and ``dark`` (a dark frame, :func:`read_dark_frame`, handed to
    the decoding) options apply to raws only; ``optics`` to every input (:func:`open_input`); ``geometry`` (a
    geometric calibration: rectify) to raws and light fields, its shape checked here (:func:`check_geometry`).
    """
    if dark is not None:        # the readers name it instead of a black level the decoding will not use
        from ..io.mosaic_levels import MosaicOptions

        dark_path = dark.path if isinstance(dark, RawCapture) else dark
        mosaic = replace(mosaic or MosaicOptions(), dark_frame=Path(dark_path).name if dark_path else "given")
    item = open_input(path, mosaic=mosaic, raytrix_xml=raytrix_xml, optics=optics)
    for name, options in (check or {}).items():
        check_product(item, name, rectified=geometry is not None, **options)
    if isinstance(item, LightField):
        return Source(lightfield=item, geometry=geometry)
    options = dict(decode_options or {})
    if dark is not None:        # its size is checked before the calibration
        options["dark"] = read_dark_frame(dark, mosaic, raw=item)
    cal = choose_calibration(item, grid=grid, white=white, database=database, self_calibrate=self_calibrate,
                             mosaic=mosaic)
    return Source(raw=item, calibration=cal, decode_options=options, progress=progress, geometry=geometry)


def load_lightfield_input(path: str | os.PathLike, **options: Any) -> LightField:
    """The light field of any input: read, or decoded (options of :func:`open_source`)."""
    return open_source(path, **options).lightfield
