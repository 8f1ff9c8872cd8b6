"""The scene's lighting for one page: viser's environment map where a graphics card draws the
page, plain lights where it draws in software.

The environment map (an HDR image, prefiltered on the page into a cube map at several
roughness levels) is drawn once per page opened, at its start: in software WebGL (headless
Chromium's SwiftShader, a machine without a graphics card) the GPU process took 7–8 s of a core
to open a page at 1400 × 900 with it, and 0.5–2 s without it.  So a page starts with a sky and
ground light and a sun, which light the scene alike, and gets the environment map once it has
said that a graphics card draws it (:meth:`Lighting.on_renderer`, from ``web.page``).
"""

from __future__ import annotations

#: the plain lights: a hemisphere (sky above, a darker ground below) and a sun from above and behind
SKY = (255, 255, 255)
GROUND = (150, 150, 160)
SKY_INTENSITY = 2.4
SUN_INTENSITY = 1.5
SUN_WXYZ = (0.88, 0.28, 0.36, 0.12)
#: viser's environment map where a graphics card draws the page (viser's default)
HDRI = "warehouse"


class Lighting:
    """One page's lights: plain ones first, the environment map once the page says a graphics
    card draws it."""

    def __init__(self, client) -> None:
        self.client = client
        self.environment = False
        self._plain: list = []
        if client is not None:
            scene = client.scene
            scene.configure_environment_map(hdri=None)
            self._plain = [
                scene.add_light_hemisphere(
                    "/nmkane/lights/sky", sky_color=SKY, ground_color=GROUND, intensity=SKY_INTENSITY
                ),
                scene.add_light_directional("/nmkane/lights/sun", intensity=SUN_INTENSITY, wxyz=SUN_WXYZ),
            ]

    def on_renderer(self, software: bool) -> None:
        """The page has said what draws it: with a graphics card, the environment map replaces
        the plain lights; in software they stay."""
        if software or self.environment or self.client is None:
            return
        self.environment = True
        self.client.scene.configure_environment_map(hdri=HDRI)
        for light in self._plain:
            light.remove()
        self._plain = []
