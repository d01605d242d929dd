"""Driving conditions: the lighting, sky, sensor model and road painters of each named condition (day, dusk,
night, rain, worn markings, shadows); the camera renders them."""

from __future__ import annotations

from dataclasses import dataclass

from testbed.errors import UserError
from testbed.ground import Lighting
from tracks.paint import ShadowPainter, WearPainter


@dataclass(frozen=True)
class Condition:
    """Lighting, sky and sensor model of one driving condition."""

    name: str
    ambient: float
    diffuse: float
    light_dir: tuple[float, float, float]
    light_rgb: tuple[float, float, float]
    sky_top: tuple[int, int, int]
    sky_horizon: tuple[int, int, int]
    exposure: float = 1.0
    contrast: float = 1.0
    blur_sigma: float = 0.0
    noise_std: float = 2.0
    headlights: bool = False
    wear: float = 0.0
    shadows: bool = False

    @property
    def lighting(self) -> Lighting:
        return Lighting(self.ambient, self.diffuse, self.light_dir, self.light_rgb)

    def track_painters(self, seed: int) -> list:
        """Painters the condition adds to the road texture (worn markings, shadow bands)."""
        painters: list = []
        if self.wear > 0:
            painters.append(WearPainter(self.wear))
        if self.shadows:
            painters.append(ShadowPainter())
        return painters


CONDITIONS: dict[str, Condition] = {
    c.name: c
    for c in (
        Condition("day", 0.65, 0.45, (0.4, 0.3, 1.0), (1.0, 1.0, 0.97), (110, 160, 220), (200, 220, 240)),
        Condition("dusk", 0.45, 0.35, (-1.0, 0.2, 0.25), (1.0, 0.75, 0.55), (60, 60, 110), (230, 140, 90),
                  exposure=0.75, contrast=0.85, noise_std=4.0),
        Condition("night", 0.30, 0.15, (0.0, 0.0, 1.0), (0.6, 0.65, 0.8), (5, 8, 18), (15, 18, 30),
                  exposure=0.22, contrast=1.0, noise_std=5.0, headlights=True),
        Condition("rain", 0.55, 0.25, (0.2, 0.2, 1.0), (0.85, 0.87, 0.9), (120, 125, 130), (150, 155, 160),
                  exposure=0.85, contrast=0.6, blur_sigma=1.1, noise_std=6.0),
        Condition("worn", 0.65, 0.45, (0.4, 0.3, 1.0), (1.0, 1.0, 0.97), (110, 160, 220), (200, 220, 240),
                  wear=0.65),
        Condition("shadows", 0.65, 0.45, (0.4, 0.3, 1.0), (1.0, 1.0, 0.97), (110, 160, 220), (200, 220, 240),
                  shadows=True),
    )
}


def get_condition(name: str) -> Condition:
    try:
        return CONDITIONS[name]
    except KeyError:
        raise UserError(f"unknown condition {name!r}; choose one of {', '.join(CONDITIONS)}") from None
