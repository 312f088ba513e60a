"""An offline meshcat window: records drawing commands instead of sending them to a server.

``meshcat.Visualizer(window=SceneRecorder())`` behaves like a visualizer connected to a meshcat
server, so Pinocchio's ``MeshcatVisualizer`` can load a robot into it, but nothing opens a
socket or a process. The recorder keeps

- the commands in the order they were sent (:attr:`SceneRecorder.commands`), to push them later
  to a live server (:mod:`ident.viz.server`);
- meshcat's own scene tree, from which :meth:`SceneRecorder.static_html` builds the same
  self-contained HTML as meshcat's server (``Visualizer.static_html()``): the viewer's JavaScript
  inlined, every command embedded as a base64 ``data:`` URL. The page needs no server and no
  network.
"""

from __future__ import annotations

import base64
import html
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import meshcat
import umsgpack
from meshcat.servers.tree import SceneTree, find_node, walk

__all__ = ["RecordedCommand", "SceneRecorder", "viewer_javascript"]

# The viewer bundle shipped with meshcat (three.js + MeshCat.Viewer), inlined in static pages.
_VIEWER_JS = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"


@dataclass(frozen=True)
class RecordedCommand:
    """One meshcat drawing command as the server receives it (three ZMQ frames)."""

    type: str
    path: str
    data: bytes  # msgpack of the lowered command


def viewer_javascript() -> str:
    """Return the text of meshcat's viewer bundle ``main.min.js``."""
    return _VIEWER_JS.read_text(encoding="utf-8")


@dataclass
class SceneRecorder:
    """Stand-in for ``meshcat.visualizer.ViewerWindow`` that records instead of sending.

    Attributes
    ----------
    commands :
        Every command received, in order.
    tree :
        meshcat's scene tree after those commands (later commands on a path replace earlier
        ones, as in meshcat's server).
    """

    commands: list[RecordedCommand] = field(default_factory=list)
    tree: Any = field(default_factory=SceneTree)
    web_url: str = "about:blank"

    def send(self, command: Any) -> None:
        """Record a meshcat command (``SetObject``, ``SetTransform``, ``SetAnimation``...)."""
        lowered = command.lower()
        data = umsgpack.packb(lowered)
        cmd_type, path = lowered["type"], lowered["path"]
        self.commands.append(RecordedCommand(cmd_type, path, data))
        # Mirror meshcat.servers.zmqserver.ZMQWebSocketBridge.handle_zmq.
        entries = [p for p in path.split("/") if p]
        if cmd_type == "set_transform":
            find_node(self.tree, entries).transform = data
        elif cmd_type == "set_object":
            node = find_node(self.tree, entries)
            node.object = data
            node.properties = []
        elif cmd_type == "set_property":
            find_node(self.tree, entries).properties.append(data)
        elif cmd_type == "set_animation":
            find_node(self.tree, entries).animation = data
        elif cmd_type == "delete":
            if entries:
                parent = find_node(self.tree, entries[:-1])
                if entries[-1] in parent:
                    del parent[entries[-1]]
            else:
                self.tree = SceneTree()

    def scene_commands(self) -> list[bytes]:
        """Return the commands that rebuild the current scene, in meshcat's server order."""
        out: list[bytes] = []
        for node in walk(self.tree):
            if node.object is not None:
                out.append(node.object)
            out.extend(node.properties)
            if node.transform is not None:
                out.append(node.transform)
            if node.animation is not None:
                out.append(node.animation)
        return out

    def static_html(self, title: str = "MeshCat", caption_html: str = "") -> str:
        """Return a self-contained HTML page showing the recorded scene.

        ``caption_html`` (trusted HTML, escaped by the caller) is shown in the top-left corner.

        The page inlines meshcat's viewer and defines a global ``viewer``
        (``MeshCat.Viewer``); it loads nothing from the network. The commands are applied in
        order once all are decoded, then ``window.identReplayReady`` becomes ``true``.
        """
        # base64 inside a JS string literal: no quote or "</script>" can occur in it.
        commands = ",\n".join(
            '"' + base64.b64encode(c).decode("ascii") + '"' for c in self.scene_commands()
        )
        caption = f'<div id="ident-caption">{caption_html}</div>' if caption_html else ""
        return _STATIC_TEMPLATE.format(
            title=html.escape(title),
            caption=caption,
            viewer_js=viewer_javascript(),
            commands=commands,
        )

    # ViewerWindow API that meshcat.Visualizer may call; an offline window has no browser.
    def open(self) -> SceneRecorder:  # pragma: no cover - never called by ident
        """Do nothing: an offline recorder has no browser to open."""
        return self


_STATIC_TEMPLATE = """<!DOCTYPE html>
<html>
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<style>
body {{ margin: 0; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
#ident-caption {{ position: absolute; left: 8px; top: 8px; padding: 4px 8px;
  font: 13px sans-serif; color: #fff; background: rgba(0, 0, 0, 0.45);
  pointer-events: none; }}
</style>
</head>
<body>
{caption}
<div id="meshcat-pane"></div>
<script>
{viewer_js}
</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
window.identReplayReady = false;
(function () {{
  // Same encoding as meshcat's static export (msgpack commands as base64 data: URLs), but
  // applied in the order they were recorded.
  const commands = [
{commands}
  ];
  Promise.all(commands.map(c => fetch("data:application/octet-binary;base64," + c)
      .then(r => r.arrayBuffer())))
    .then(buffers => {{
      for (const b of buffers) viewer.handle_command_bytearray(new Uint8Array(b));
      window.identReplayReady = true;
    }});
}})();
</script>
</body>
</html>
"""
