"""Camera presets of the synthetic generator: sensor, micro-lens array, optics, levels, colour and noise.

:data:`PRESETS` holds the simulated cameras by name (Lytro Illum and F01 at full size and as
small crops, a square-lattice light-field microscope with its optics, a Raytrix-like focused camera);
:func:`get_preset` looks one up.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..optics import MicroscopeOptics


@dataclass(frozen=True)
class Preset:
    """A simulated camera: sensor, MLA, optics, levels, colour and noise.

    Lengths in metres unless the name says px; angles in radians.
    """

    name: str
    sensor_shape: tuple[int, int]          # (H, W)
    pitch_px: float                        # lens pitch along a lens row
    lattice: str = "hex"                   # 'hex' or 'square'
    rotation: float = 0.0
    offset: tuple[float, float] = (0.0, 0.0)   # lattice anchor shift from the sensor centre (row, col) px
    cfa: str | None = "GRBG"
    bits: int = 10                         # bits of the data
    black: float = 64.0
    white: float = 1023.0
    radius_frac: float = 0.46              # disk radius / pitch
    edge_px: float = 1.5                   # width of the soft disk edge
    disk_falloff: float = 0.12             # relative loss at the disk radius (mild radial falloff)
    vignette_corner: float = 0.5           # sensor vignetting at the corners
    exposure: float = 0.8                  # white-image signal at the sensor centre, fraction of range
    full_well: float = 4000.0              # electrons at the white level
    read_noise_dn: float = 2.0
    hot_fraction: float = 2e-5
    focused: bool = False                  # focused plenoptic (Raytrix)
    type_focus: tuple[float, ...] = (1.5, 3.3, 7.3)   # focused: virtual depth each lens type images sharply
    texel_px: float = 4.0                  # focused: sensor px per scene-texture unit in the virtual image
    make: str = "Lytro"
    model: str = "ILLUM"
    serial: str = "B5143909630"
    pixel_pitch_m: float = 1.4e-6
    lens_pitch_m: float = 2.0e-5
    mla_gap_m: float = 3.9e-5
    zoom_step: float | None = None
    focus_step: float | None = None
    focal_length_m: float | None = None
    f_number: float | None = None
    exposure_s: float = 1.0 / 125.0
    iso: float = 100.0
    wb_gains: tuple[float, float, float, float] | None = None    # (r, gr, gb, b)
    ccm: tuple[tuple[float, float, float], ...] | None = None   # camera RGB -> linear sRGB, rows sum to 1
    microscope: MicroscopeOptics | None = None   # light-field microscope optics (the 'square' preset)

    @property
    def mono(self) -> bool:
        """True for a sensor without a colour filter array."""
        return self.cfa is None

    def camera_matrix(self) -> np.ndarray:
        """``M = diag(1 / wb) @ inv(ccm)``: linear sRGB -> camera RGB, (3, 3) float64 (identity if mono)."""
        if self.ccm is None or self.wb_gains is None:
            return np.eye(3)
        r, gr, gb, b = self.wb_gains
        return np.diag([1.0 / r, 2.0 / (gr + gb), 1.0 / b]) @ np.linalg.inv(np.asarray(self.ccm, np.float64))


_ILLUM_CCM = ((1.6182, -0.5113, -0.1069), (-0.2261, 1.4870, -0.2609), (0.0452, -0.6216, 1.5764))
_F01_CCM = ((1.7013, -0.5646, -0.1367), (-0.2994, 1.5633, -0.2639), (-0.0139, -0.6742, 1.6881))

_ILLUM = Preset(
    name="illum", sensor_shape=(5368, 7728), pitch_px=2.0e-5 / 1.4e-6, rotation=6e-4, offset=(0.37, -0.21),
    cfa="GRBG", bits=10, black=64.0, white=1023.0, make="Lytro", model="ILLUM", serial="B5143909630",
    pixel_pitch_m=1.4e-6, lens_pitch_m=2.0e-5, mla_gap_m=3.9e-5, zoom_step=-312.0, focus_step=417.0,
    focal_length_m=0.0301, f_number=2.0, exposure_s=1.0 / 125.0, iso=200.0,
    wb_gains=(1.379, 1.0, 1.0, 1.148), ccm=_ILLUM_CCM)

_F01 = Preset(
    name="f01", sensor_shape=(3280, 3280), pitch_px=1.38986e-5 / 1.4e-6, rotation=0.00193, offset=(0.4, -1.94),
    cfa="BGGR", bits=12, black=168.0, white=4095.0, make="Lytro", model="F01", serial="A000424242",
    pixel_pitch_m=1.4e-6, lens_pitch_m=1.38986e-5, mla_gap_m=2.5e-5, zoom_step=981.0, focus_step=582.0,
    focal_length_m=0.00645, f_number=2.0, exposure_s=1.0 / 60.0, iso=100.0,
    wb_gains=(1.0, 1.117, 1.117, 1.723), ccm=_F01_CCM)

#: Simulated cameras by name.  ``pitch``, ``rotation``, ``offset`` and ``shape`` can be
#: overridden per call.
PRESETS: dict[str, Preset] = {
    "illum": _ILLUM,
    "illum-mini": replace(_ILLUM, name="illum-mini", sensor_shape=(1072, 1544)),
    "f01": _F01,
    "f01-mini": replace(_F01, name="f01-mini", sensor_shape=(656, 656)),
    "square": Preset(
        name="square", sensor_shape=(1100, 1100), pitch_px=27.5, lattice="square", rotation=0.0015,
        offset=(0.23, -0.31), cfa=None, bits=12, black=100.0, white=4095.0, radius_frac=0.47,
        make="plenodecode", model="LFM-synthetic", serial="LFM-0001", pixel_pitch_m=4.55e-6,
        lens_pitch_m=1.25e-4, mla_gap_m=2.5e-3, focal_length_m=None, f_number=None,
        exposure_s=0.05, iso=None, full_well=8000.0,
        # the optics of the LFAnalyze ant-leg capture: 20x / 0.5 NA water objective, 180 mm tube lens,
        # 125 um f/20 micro-lenses (2433 um), 4.55 um effective pixels
        microscope=MicroscopeOptics(lens_pitch_m=1.25e-4, pixel_pitch_m=4.55e-6, magnification=20.0,
                                    numerical_aperture=0.5, tube_lens_focal_length_m=0.18, medium_index=1.33,
                                    microlens_focal_length_m=2.433e-3, wavelength_m=5.1e-7)),
    "raytrix": Preset(
        name="raytrix", sensor_shape=(700, 1000), pitch_px=34.86, lattice="hex", rotation=0.0008,
        offset=(0.31, 0.12), cfa=None, bits=12, black=0.0, white=4095.0, radius_frac=0.47, focused=True,
        make="Raytrix", model="R42-synthetic", serial="RX-0042", pixel_pitch_m=5.5e-6,
        lens_pitch_m=34.86 * 5.5e-6, mla_gap_m=2.0e-4, focal_length_m=0.035, f_number=2.4,
        exposure_s=0.01, iso=None, full_well=10000.0),
}


def get_preset(preset: str | Preset) -> Preset:
    """Look up a preset by name (ValueError listing the names) or pass a Preset through."""
    if isinstance(preset, Preset):
        return preset
    try:
        return PRESETS[preset]
    except (KeyError, TypeError):
        raise ValueError(f"preset must be one of {sorted(PRESETS)}, got {preset!r}") from None


__all__ = ["Preset", "PRESETS", "get_preset"]
