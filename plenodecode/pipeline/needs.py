"""What a product asks of the input's metadata, checked as soon as the input is read (before the calibration,
which may self-calibrate for seconds, and before any decoding).

Part of :mod:`plenodecode.pipeline` (see its docstring for the five steps): :func:`~plenodecode.pipeline.
open_source` runs :func:`check_product` between step 1 (read) and step 2 (calibrate); :func:`~plenodecode.
pipeline.render_product` runs it again for a :class:`~plenodecode.pipeline.Source` made by hand.

Today one request needs metadata: Ng's relative film depth alpha, turned into a slope by
:func:`plenodecode.render.alpha.alpha_to_slope` with the camera constants of
:data:`~plenodecode.render.alpha.REFOCUS_CONSTANTS`.  It is asked by the 'refocus' product (``alpha=``) and by
the 'focal-stack' product (``units='alpha'``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Mapping

from ..errors import RefocusConstantsError
from ..types import LightField, RawCapture


def _refocus_alpha(options: Mapping[str, Any]) -> str | None:
    return "alpha" if options.get("alpha") is not None else None


def _stack_alpha(options: Mapping[str, Any]) -> str | None:
    return "units" if options.get("units") == "alpha" else None


#: Product -> ``fn(options) -> the keyword that asks for alpha, or None``: every place where the workflow turns an
#: alpha into a slope (:func:`~plenodecode.render.refocus_methods.focus_slope` for 'refocus', the 'alpha' entry
#: of :data:`~plenodecode.pipeline.products.STACK_UNITS` for 'focal-stack').
ALPHA_REQUESTS: dict[str, Callable[[Mapping[str, Any]], str | None]] = {
    "refocus": _refocus_alpha,
    "focal-stack": _stack_alpha,
}

#: What to use instead of alpha, per keyword (library spelling; the CLI names its own options).
ALPHA_INSTEAD = {"alpha": "refocus by slope instead", "units": "give START and STOP as slopes (units='slope')"}


def _name(item: LightField | RawCapture) -> str:
    """The file name of the input, as an error message names it."""
    path = item.path if isinstance(item, RawCapture) else item.geometry.source
    return Path(path).name if path else ("the raw" if isinstance(item, RawCapture) else "the light field")


def check_product(item: LightField | RawCapture, name: str, **options: Any) -> None:
    """Refuse a product request that the input's metadata cannot serve, without calibrating or decoding.

    Parameters
    ----------
    item : RawCapture or LightField
        The input as read (a raw's :class:`~plenodecode.types.CameraMetadata` stands for the light field it
        decodes to: :func:`plenodecode.render.alpha.missing_refocus_constants`).
    name : str
        A product of :data:`~plenodecode.pipeline.PRODUCTS` (products that ask nothing of the metadata pass).
    **options
        The product's options, as :func:`~plenodecode.pipeline.render_product` takes them.

    Raises
    ------
    RefocusConstantsError
        Alpha was asked (``alpha=`` of 'refocus', ``units='alpha'`` of 'focal-stack') and the metadata lacks a
        camera constant of the conversion; ``keyword`` names the option, ``missing`` the constants.
    """
    request = ALPHA_REQUESTS.get(name)
    keyword = request(options) if request is not None else None
    if keyword is None:
        return
    from ..render.alpha import missing_refocus_constants

    missing = missing_refocus_constants(item.metadata if isinstance(item, RawCapture) else item)
    if missing:
        source = _name(item)
        raise RefocusConstantsError(
            f"{source}: alpha needs the camera constant{'s' * (len(missing) > 1)} {', '.join(missing)}, which its "
            f"metadata does not have; {ALPHA_INSTEAD[keyword]}", keyword=keyword, missing=missing, source=source)


__all__ = ["ALPHA_REQUESTS", "check_product"]
