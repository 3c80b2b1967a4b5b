"""Memory with real embeddings from llama.cpp's OpenAI-compatible server (SmolLM2, mean pooling), and on Zenoh."""

from __future__ import annotations

from pathlib import Path

import pytest

from agents_core import Launcher, Topic
from agents_core.clients import GenericHTTPClient
from agents_core.components import MemLayer, Memory
from agents_core.config import MemoryConfig
from agents_core.messages import Header, OdometryMsg, PoseMsg
from agents_core.models import GenericLLM

from ..clients.test_generic_client import API_KEY, LlamaServer, llama_server  # noqa: F401  (a fixture)
from ..conftest import wait_for

pytest.importorskip("emem", reason="the memory extra is not installed (pip install 'agents-core[memory]')")

ODOM, HEARD = Topic("odom", "Odometry"), Topic("heard", "String")


@pytest.mark.local_models
def test_semantic_search_on_real_embeddings_survives_a_restart(tmp_path: Path,
                                                               llama_server: LlamaServer) -> None:  # noqa: F811
    def build() -> Memory:
        client = GenericHTTPClient(GenericLLM(name="embed", checkpoint="smollm2-embed"), port=llama_server.port,
                                   api_key=API_KEY, inference_timeout=60)
        return Memory(layers=[MemLayer(subscribes_to=HEARD, temporal_change=True)], position=ODOM,
                      embedding_client=client, config=MemoryConfig(db_path=str(tmp_path / "real.db"),
                                                                   flush_interval=0.0), trigger=10.0)

    m = build()
    launcher = Launcher("memory")
    launcher.add_pkg(components=[m])
    places = {"the kitchen has a red kettle on the stove": (1.0, 1.0),
              "the garage holds a bicycle and a lawn mower": (9.0, -4.0),
              "the bedroom has a bed with blue pillows": (-6.0, 3.0)}
    with launcher:
        pub_odom, pub_heard = launcher.transport.create_publisher(ODOM), launcher.transport.create_publisher(HEARD)
        for text, (x, y) in places.items():
            pub_odom.publish(OdometryMsg(pose=PoseMsg(position=[x, y, 0.0]), header=Header(frame_id="map")))
            assert wait_for(lambda x=x: m._fix is not None and m._fix.x == x)
            pub_heard.publish(text)
            assert wait_for(lambda t=text: m._last_stored.get("heard", ("",))[0] == t, timeout=30)
        assert wait_for(lambda: m.stats["stored"] == 3 and m.stats["pending"] == 0, timeout=60), m.stats
    again = build()
    restarted = Launcher("memory")
    restarted.add_pkg(components=[again])
    with restarted:
        found = again.semantic_search(query="the garage holds a bicycle and a lawn mower", n_results=1)
    assert "bicycle" in found and "9.0" in found
