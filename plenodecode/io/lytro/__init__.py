"""Lytro LFP/LFR containers, packed raws, ``MOD_NNNN.RAW`` + ``.TXT`` pairs and their metadata.

Implements ``formats.md`` §1-3, one concern per module (each imports only those above it):

* :mod:`.fields` -- safe lookups in Lytro JSON (TOCs, metadata, sidecars);
* :mod:`.metadata` -- both metadata schemas, F01 / white-image ``image.rawDetails.*`` and Illum
  ``image.pixelFormat/pixelPacking/mosaic``, read (:func:`metadata_from_lytro`) and generated
  (:func:`lytro_metadata`);
* :mod:`.contents` -- what a container holds (:class:`ContentItem`: raw, JSON, JPEG/H.264 stacks,
  depth maps, calibration-archive files), found through the TOC's SHA-1 references;
* :mod:`.container` -- the container grammar (16-byte file header, then 16-byte aligned sections
  ``LFM``/``LFC`` of ``96 + N`` bytes: magic, length N, ``sha1-<hex>`` name, payload), with payloads
  resolved only through the SHA-1 names the LFM table of contents (TOC) refers to;
* :mod:`.lfp` -- the raw of an F01 ``.lfp`` / Illum ``.lfr``, writers of both, payload extraction;
* :mod:`.rawpair` -- headerless raws with a JSON sidecar (``MOD_NNNN.RAW`` + ``.TXT`` white images);
* :mod:`.archive` -- calibration archives read in place (Illum ``caldata-<serial>.tar``, F01
  ``data.C.N`` volumes), their members named ``ARCHIVE::MEMBER``, and ``cal_file_manifest.json``.

Raw payload packings are in :mod:`plenodecode.io.packing`.  Readers never write; writers write to a
temporary name and rename.
"""

from __future__ import annotations

from .. import packing
from .container import LytroContainer, Section, read_container, section_name, write_container
from .contents import ContentItem
from .fields import lookup
from .lfp import (TOC_FILE, content_file_name, extract_contents, frame_ref, preview_file_name, read_lytro,
                  read_modulation_white, write_lfp, write_lfr)
from .metadata import lytro_metadata, metadata_from_lytro
from .rawpair import find_sidecar, read_raw_pair, read_raw_pair_metadata, read_sidecar, write_raw_pair

__all__ = [
    "Section", "ContentItem", "LytroContainer", "read_container", "read_lytro", "metadata_from_lytro",
    "find_sidecar", "read_raw_pair", "read_raw_pair_metadata", "write_container", "write_lfr", "write_lfp",
    "write_raw_pair", "extract_contents", "content_file_name", "preview_file_name", "TOC_FILE", "lytro_metadata",
    "section_name", "lookup",
    "read_sidecar", "pack_10bit", "unpack_10bit", "pack_12bit", "unpack_12bit", "frame_ref", "read_modulation_white",
]

pack_10bit = packing.pack_10bit
unpack_10bit = packing.unpack_10bit
pack_12bit = packing.pack_12bit
unpack_12bit = packing.unpack_12bit
