"""The page in a real browser: Debian's headless Chromium driven by Playwright.

Each test saves screenshots under its tmp_path and copies them to ``test-artifacts/ui/``.
Skipped, saying why, when ``/usr/bin/chromium`` or Playwright is absent (``nox -s tests``
installs both on a machine where it runs as root with apt).
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("starlette", reason="the ui extra is not installed (pip install 'agents-core[ui]')")
pytest.importorskip("playwright", reason="playwright is not installed (pip install playwright)")
CHROMIUM = Path("/usr/bin/chromium")
if not CHROMIUM.is_file():
    pytest.skip("Debian's Chromium is not at /usr/bin/chromium (apt-get install -y chromium)", allow_module_level=True)

from playwright.sync_api import Page, sync_playwright  # noqa: E402

from agents_core import Launcher, Topic  # noqa: E402

from ..conftest import free_tcp_port  # noqa: E402
from .ui_parts import SHOUTS, WORDS, shouter  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
ARTIFACTS = REPO / "test-artifacts" / "ui"
TIMEOUT_MS = 30_000


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with sync_playwright() as p:
        chromium = p.chromium.launch(executable_path=str(CHROMIUM), args=["--no-sandbox"])
        yield chromium
        chromium.close()


@pytest.fixture
def page(browser: Any) -> Iterator[Page]:
    context = browser.new_context(viewport={"width": 1400, "height": 900})
    tab = context.new_page()
    yield tab
    context.close()


def _shot(page: Page, tmp_path: Path, name: str) -> Path:
    path = tmp_path / f"{name}.png"
    page.screenshot(path=str(path), full_page=True)
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    shutil.copy(path, ARTIFACTS / path.name)
    return path


def _open(page: Page, url: str) -> None:
    page.goto(url)
    page.wait_for_selector("#connection.ok", timeout=TIMEOUT_MS)  # the output socket is live


def test_llm_demo_streams_the_answer_word_by_word(page: Page, tmp_path: Path) -> None:
    from ..components.models_dir import needs_smollm2  # noqa: PLC0415

    needs_smollm2()
    from agents_core.demo import build_agent  # noqa: PLC0415

    llm, question, answer = build_agent(max_new_tokens=24)
    launcher = Launcher("memory")
    launcher.add_pkg(components=[llm])
    launcher.enable_ui(inputs=[question], outputs=[answer], port=0)
    with launcher:
        _open(page, launcher.ui.url)
        # Record every text the answer bubble shows, as the browser renders it.
        page.evaluate("""() => { window.seen = []; new MutationObserver(() => {
            const b = document.querySelector('.msg.agent[data-topic="answer"] .text');
            if (b && window.seen[window.seen.length - 1] !== b.textContent) window.seen.push(b.textContent);
        }).observe(document.querySelector('#chat'), {subtree: true, childList: true, characterData: true}); }""")
        box = page.locator('input[data-topic="question"]')
        box.fill("What is the capital of France?")
        box.press("Enter")
        page.wait_for_selector('.msg.user:has-text("capital of France")', timeout=TIMEOUT_MS)
        page.wait_for_selector('.msg.agent[data-topic="answer"][data-done="true"]', timeout=120_000)
        _shot(page, tmp_path, "llm_answer")
        seen: list[str] = page.evaluate("window.seen")
        chunks = int(page.get_attribute('.msg.agent[data-topic="answer"]', "data-chunks") or 0)
    final = seen[-1]
    assert final.strip(), "the answer has text"
    assert chunks >= 3 and len(seen) >= 3, f"the answer came in one piece: {seen}"
    assert all(final.startswith(partial) for partial in seen), "each view of the answer extends the previous one"


def test_an_uploaded_photo_comes_back_with_its_boxes(page: Page, tmp_path: Path) -> None:
    from ..components.vision_recipe import SHARED_IMAGES, needs_ssd  # noqa: PLC0415

    model = needs_ssd()
    from agents_core.components import Vision  # noqa: PLC0415
    from agents_core.config import VisionConfig  # noqa: PLC0415

    camera, objects = Topic("camera", "Image"), Topic("objects", "Detections")
    vision = Vision(inputs=[camera], outputs=[objects], trigger=camera, component_name="vision",
                    config=VisionConfig(enable_local_model=True, local_model_path=model, include_image=True))
    launcher = Launcher("memory")
    launcher.add_pkg(components=[vision])
    launcher.enable_ui(inputs=[camera], outputs=[objects], port=0)
    with launcher:
        _open(page, launcher.ui.url)
        page.set_input_files('input[type="file"][data-topic="camera"]', str(SHARED_IMAGES / "coffee.png"))
        page.wait_for_selector('canvas[data-topic="objects"][data-boxes]', timeout=60_000)
        _shot(page, tmp_path, "vision_coffee")
        labels = page.locator('.panel[data-topic="objects"] li.detection').all_inner_texts()
        size = page.evaluate("() => { const c = document.querySelector('canvas[data-topic=\"objects\"]');"
                             " return [c.width, c.height]; }")
        # The first box's left edge, half way down, is drawn in the first box colour (#ff1744).
        pixel = page.evaluate("""() => { const c = document.querySelector('canvas[data-topic="objects"]');
            const [x1, y1, x2, y2] = JSON.parse(c.dataset.boxList)[0];
            const at = [Math.round(x1), Math.round((y1 + y2) / 2)];
            return Array.from(c.getContext('2d').getImageData(at[0], at[1], 1, 1).data); }""")
    assert any(label.startswith("cup") for label in labels), labels
    assert size[0] > 100 and size[1] > 100, size
    assert pixel[0] > 200 and pixel[1] < 80 and pixel[2] < 120, f"no box drawn at the box's edge: {pixel}"


def test_deactivate_and_activate_buttons_change_the_state(page: Page, tmp_path: Path) -> None:
    component = shouter()
    launcher = Launcher("memory")
    launcher.add_pkg(components=[component])
    launcher.enable_ui(inputs=[WORDS], outputs=[SHOUTS], port=0)
    with launcher:
        _open(page, launcher.ui.url)
        card = page.locator('.component[data-name="shouter"]')
        assert card.get_attribute("data-state") == "active"
        card.locator('button[data-transition="deactivate"]').click()
        page.wait_for_selector('.component[data-name="shouter"][data-state="inactive"]', timeout=TIMEOUT_MS)
        assert component.lifecycle_state.value == "inactive"
        _shot(page, tmp_path, "component_inactive")
        card.locator('button[data-transition="activate"]').click()
        page.wait_for_selector('.component[data-name="shouter"][data-state="active"]', timeout=TIMEOUT_MS)
        assert component.lifecycle_state.value == "active"
        assert card.locator(".state").inner_text() == "active"
        _shot(page, tmp_path, "component_active")


@pytest.mark.zenoh
def test_the_ui_attached_over_zenoh_to_a_recipe_in_another_process(page: Page, tmp_path: Path) -> None:
    pytest.importorskip("zenoh", reason="the zenoh extra is not installed")
    from agents_core.transport.registry import resolve_transport  # noqa: PLC0415
    from agents_core.ui.attach import attach  # noqa: PLC0415

    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    recipe = subprocess.Popen([sys.executable, "-m", "tests.ui.ui_parts", "--listen", endpoint], cwd=REPO,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        assert recipe.stdout is not None
        assert recipe.stdout.readline().strip() == "READY", "the recipe process did not start"
        transport = resolve_transport("zenoh", mode="peer", connect=[endpoint], listen=[],
                                      multicast_scouting=False)
        try:
            server = attach(transport, components=["shouter"])
            try:
                _open(page, server.url)
                page.wait_for_selector('.component[data-name="shouter"][data-state="active"]', timeout=TIMEOUT_MS)
                box = page.locator('input[data-topic="words"]')
                box.fill("over zenoh")
                box.press("Enter")
                page.wait_for_selector('.msg.agent[data-topic="shouts"]:has-text("OVER ZENOH!")', timeout=TIMEOUT_MS)
                _shot(page, tmp_path, "attached_over_zenoh")
                page.locator('.component[data-name="shouter"] button[data-transition="deactivate"]').click()
                page.wait_for_selector('.component[data-name="shouter"][data-state="inactive"]', timeout=TIMEOUT_MS)
            finally:
                server.stop()
        finally:
            transport.close()
    finally:
        recipe.send_signal(signal.SIGTERM)
        try:
            recipe.wait(timeout=20)
        except subprocess.TimeoutExpired:
            recipe.kill()
            recipe.wait(timeout=10)
        for stream in (recipe.stdout, recipe.stderr):
            if stream is not None:
                stream.close()


def test_a_60_hz_camera_is_drawn_at_30_fps_or_more(page: Page, tmp_path: Path) -> None:
    """Issue 29, item 3: binary frames, drawn once per display refresh, keep up with a 640x480 camera."""
    import threading  # noqa: PLC0415
    import time  # noqa: PLC0415

    import numpy as np  # noqa: PLC0415

    camera = Topic("camera", "Image")
    launcher = Launcher("memory")
    launcher.add_pkg(components=[shouter()])
    launcher.enable_ui(inputs=[WORDS], outputs=[camera], port=0)
    from PIL import Image as PILImage  # noqa: PLC0415

    from ..components.vision_recipe import SHARED_IMAGES  # noqa: PLC0415

    # Camera-like frames (photos, 640x480), each with a moving noise band so no two are alike.
    photos = [np.asarray(PILImage.open(SHARED_IMAGES / name).convert("RGB").resize((640, 480)))
              for name in ("coffee.png", "chelsea.png", "astronaut.png", "motorcycle_left.png")
              if (SHARED_IMAGES / name).is_file()]
    if not photos:
        pytest.skip(f"no photos in {SHARED_IMAGES}")
    rng = np.random.default_rng(0)
    frames = []
    for i in range(8):
        frame = photos[i % len(photos)].copy()
        frame[i * 40:(i * 40) + 40] = rng.integers(0, 255, (40, 640, 3), dtype=np.uint8)
        frames.append(frame)
    stop = threading.Event()
    with launcher:
        publisher = launcher.transport.create_publisher(camera)

        def publish_at_60_hz() -> None:
            next_at, seq = time.perf_counter(), 0
            while not stop.is_set() and seq < 60 * 30:  # bounded: 30 s at most
                publisher.publish(frames[seq % len(frames)])
                seq += 1
                next_at += 1 / 60
                time.sleep(max(0.0, next_at - time.perf_counter()))

        _open(page, launcher.ui.url)
        camera_thread = threading.Thread(target=publish_at_60_hz, daemon=True)
        camera_thread.start()
        try:
            page.wait_for_function("window.uiStats.drawn > 10", timeout=TIMEOUT_MS)
            before = page.evaluate("[window.uiStats.drawn, performance.now()]")
            page.wait_for_timeout(3000)
            after = page.evaluate("[window.uiStats.drawn, performance.now(), window.uiStats.bad]")
            _shot(page, tmp_path, "camera_60hz")
        finally:
            stop.set()
            camera_thread.join(timeout=10)
        health = launcher.ui.state.hub
        dropped = health.dropped_frames
    fps = (after[0] - before[0]) / ((after[1] - before[1]) / 1000)
    print(f"browser drew {fps:.1f} fps of a 60 Hz 640x480 camera; server dropped {dropped} frames (latest-wins)")
    assert after[2] == 0, "the page refused frames it should have drawn"
    assert fps >= 30, f"the page drew {fps:.1f} frames per second of a 60 Hz camera"
