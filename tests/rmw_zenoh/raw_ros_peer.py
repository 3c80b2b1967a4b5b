"""A ROS 2 peer in rmw_zenoh's format built from zenoh-python, rosbags, xxhash and the installed type descriptions.

None of agents_zenoh's code: keys and tokens are written here, CDR by rosbags, attachments by zenoh.ext, type hashes
read from ``share/<pkg>/<kind>/<Type>.json``. Usage: ``python raw_ros_peer.py ROUTER DOMAIN MODE [ARG]``:

- ``talk TOPIC``: declare a node and a publisher of std_msgs/String, publish "raw 1".."raw 50" (20 ms apart);
- ``listen TOPIC``: print one JSON line per String sample: data, sequence number, whether the GID is the hash of
  a publisher token seen on the topic;
- ``call SERVICE``: one JsonCall query ``{"from": "raw"}``, print the reply and whether seq / GID were echoed;
- ``get_state NODE``: one lifecycle_msgs/GetState query, print the label;
- ``serve SERVICE``: serve JsonCall (reply ``{"raw_got": <request>}``) until stdin closes;
- ``node NODE``: wait (up to 20 s) for the node token of the node called NODE and for its lifecycle services, then
  print its namespace and name as the token says, and the names of the entities that token's node owns.
"""

from __future__ import annotations

import json
import sys
import time

import zenoh
from raw_wire import SHARE, attachment, dds, gid, installed_hash, open_session, read_attachment, store
from rosbags.typesys import get_types_from_msg

ROUTER, DOMAIN, MODE = sys.argv[1], int(sys.argv[2]), sys.argv[3]
ARG = sys.argv[4] if len(sys.argv) > 4 else ""


def load_service(ros_type: str) -> tuple[str, str]:
    pkg, _, name = ros_type.split("/")
    text = (SHARE / pkg / "srv" / f"{name}.srv").read_text()
    request, response = text.split("\n---\n") if not text.startswith("---") else ("", text[4:])
    req, res = f"{pkg}/msg/{name}_Request", f"{pkg}/msg/{name}_Response"
    store.register({**get_types_from_msg(request or "uint8 structure_needs_at_least_one_member", req),
                    **get_types_from_msg(response, res)})
    return req, res


session = open_session(ROUTER)
zid = str(session.zid())
node = "raw_peer"
tokens = [session.liveliness().declare_token(f"@ros2_lv/{DOMAIN}/{zid}/0/0/NN/%/%/{node}")]


def entity(kind: str, eid: int, name: str, ros_type: str, qos: str = "::,10:,:,:,,") -> tuple[str, bytes]:
    h = installed_hash(ros_type)
    token = f"@ros2_lv/{DOMAIN}/{zid}/0/{eid}/{kind}/%/%/{node}/{name.replace('/', '%')}/{dds(ros_type)}/{h}/{qos}"
    tokens.append(session.liveliness().declare_token(token))
    return f"{DOMAIN}/{name.strip('/')}/{dds(ros_type)}/{h}", gid(token)


if MODE == "talk":
    key, g = entity("MP", 1, ARG, "std_msgs/msg/String")
    pub = session.declare_publisher(key)
    time.sleep(0.5)
    for i in range(1, 51):
        pub.put(bytes(store.serialize_cdr(store.types["std_msgs/msg/String"](data=f"raw {i}"), "std_msgs/msg/String")),
                attachment=attachment(i, g))
        time.sleep(0.02)
elif MODE == "listen":
    key, _ = entity("MS", 1, ARG, "std_msgs/msg/String")
    publisher_gids: set[bytes] = set()

    def on_token(sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT and "/MP/" in str(sample.key_expr):
            publisher_gids.add(gid(str(sample.key_expr)))

    watch = session.liveliness().declare_subscriber(f"@ros2_lv/{DOMAIN}/**", on_token, history=True)

    def on_sample(sample: zenoh.Sample) -> None:
        seq, _stamp, g = read_attachment(sample.attachment)
        for _ in range(100):  # the publisher's token may reach us just after its first sample
            if g in publisher_gids:
                break
            time.sleep(0.01)
        msg = store.deserialize_cdr(sample.payload.to_bytes(), "std_msgs/msg/String")
        print(json.dumps({"data": msg.data, "seq": seq, "gid_of_a_publisher_token": g in publisher_gids}), flush=True)

    sub = session.declare_subscriber(key, on_sample)
    print("ready", flush=True)
    sys.stdin.read()
elif MODE in ("call", "get_state"):
    ros_type = "agents_interfaces/srv/JsonCall" if MODE == "call" else "lifecycle_msgs/srv/GetState"
    req_t, res_t = load_service(ros_type)
    name = ARG if MODE == "call" else f"/{ARG}/get_state"
    key, g = entity("SC", 1, name, ros_type)
    request = (store.types[req_t](request_json=json.dumps({"from": "raw"})) if MODE == "call"
               else store.types[req_t](structure_needs_at_least_one_member=0))
    body = bytes(store.serialize_cdr(request, req_t))
    out: dict[str, object] = {"replies": 0}
    for _attempt in range(20):
        for reply in session.get(key, payload=body, attachment=attachment(7, g), timeout=2.0,
                                 target=zenoh.QueryTarget.ALL_COMPLETE):
            if reply.ok is None:
                continue
            seq, _stamp, echoed = read_attachment(reply.ok.attachment)
            response = store.deserialize_cdr(reply.ok.payload.to_bytes(), res_t)
            out = {"replies": 1, "seq_echoed": seq == 7, "gid_echoed": echoed == g,
                   "reply": (json.loads(response.response_json) if MODE == "call"
                             else response.current_state.label)}
            if MODE == "call":
                out["success"] = bool(response.success)
        if out["replies"]:
            break
        time.sleep(0.2)
    print(json.dumps(out), flush=True)
elif MODE == "serve":
    req_t, res_t = load_service("agents_interfaces/srv/JsonCall")
    key, _ = entity("SS", 1, ARG, "agents_interfaces/srv/JsonCall")

    def on_query(query: zenoh.Query) -> None:
        with query:
            seq, _stamp, client = read_attachment(query.attachment)
            assert query.payload is not None
            request = store.deserialize_cdr(query.payload.to_bytes(), req_t)
            answer = store.types[res_t](success=True, error="",
                                        response_json=json.dumps({"raw_got": json.loads(request.request_json)}))
            query.reply(key, bytes(store.serialize_cdr(answer, res_t)), attachment=attachment(seq, client))

    queryable = session.declare_queryable(key, on_query, complete=True)
    print("ready", flush=True)
    sys.stdin.read()
elif MODE == "node":
    seen: dict[str, list[str]] = {}

    def on_any(sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT:  # @ros2_lv/d/zid/nid/eid/kind/enclave/namespace/node[/name/...]
            parts = [p.replace("%", "/") for p in str(sample.key_expr).split("/")]
            seen[str(sample.key_expr)] = parts

    watch = session.liveliness().declare_subscriber(f"@ros2_lv/{DOMAIN}/**", on_any, history=True)
    found: dict[str, object] = {}
    for _ in range(200):
        nodes = [p for p in list(seen.values()) if p[5] == "NN" and p[8] == ARG]
        if nodes:
            ns, nid = nodes[0][7], nodes[0][3]
            owned = sorted(p[9] for p in list(seen.values()) if p[5] != "NN" and p[3] == nid and p[8] == ARG
                           and p[7] == ns)
            found = {"namespace": ns, "node": ARG, "owned": owned,
                     "others_named_like_it": sorted(p[8] for p in list(seen.values()) if p[5] == "NN"
                                                    and ARG in p[8] and p[8] != ARG)}
            if any(name.endswith("/change_state") for name in owned):
                break
        time.sleep(0.1)
    print(json.dumps(found), flush=True)
for token in tokens:
    token.undeclare()
session.close()
