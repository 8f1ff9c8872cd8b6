"""A page's lighting (web.lighting): plain lights until the page says a graphics card draws it,
then viser's environment map; in software WebGL the plain lights stay (the environment map's
prefiltering cost 7–8 s of a core per page opened in headless Chromium)."""

from web.lighting import HDRI, Lighting


class _Light:
    def __init__(self, log, name):
        self.log, self.name = log, name

    def remove(self):
        self.log.append(("remove", self.name))


class _Scene:
    def __init__(self):
        self.log = []

    def configure_environment_map(self, hdri="warehouse", **_):
        self.log.append(("environment", hdri))

    def add_light_hemisphere(self, name, **_):
        self.log.append(("hemisphere", name))
        return _Light(self.log, name)

    def add_light_directional(self, name, **_):
        self.log.append(("directional", name))
        return _Light(self.log, name)


class _Client:
    def __init__(self):
        self.scene = _Scene()


def test_a_page_starts_with_plain_lights_and_no_environment_map():
    client = _Client()
    Lighting(client)
    kinds = [k for k, _ in client.scene.log]
    assert kinds[0] == "environment" and client.scene.log[0][1] is None  # before anything is drawn
    assert "hemisphere" in kinds and "directional" in kinds and "remove" not in kinds


def test_a_graphics_card_gets_the_environment_map_instead_once():
    client = _Client()
    lighting = Lighting(client)
    lighting.on_renderer(software=False)
    lighting.on_renderer(software=False)  # a second answer changes nothing
    after = client.scene.log[3:]
    assert after.count(("environment", HDRI)) == 1
    assert sorted(k for k, _ in after if k == "remove") == ["remove", "remove"]
    assert lighting.environment


def test_software_webgl_keeps_the_plain_lights():
    client = _Client()
    lighting = Lighting(client)
    lighting.on_renderer(software=True)
    assert len(client.scene.log) == 3 and not lighting.environment


def test_a_session_without_a_browser_sends_nothing():
    lighting = Lighting(None)  # a test's shared server scene: no client to send to
    lighting.on_renderer(software=False)  # (without its check for no client: AttributeError)
    assert not lighting.environment
