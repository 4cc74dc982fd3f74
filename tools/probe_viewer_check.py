"""The probe viewer in headless Chromium: run by tools/probe-viewer-check.

    python3 tools/probe_viewer_check.py BAKED.gltf --at X,Y,Z [--from X,Y,Z] [--rho R,G,B]
        [--radius R] [--size N] [--no-room] [--screenshot PNG]

Serves tools/probe-viewer.html and .js, three.js (tools/.three) and BAKED's folder, opens the
page with `post=1` and prints `PROBE_VIEWER {...}`: the JSON the page posts (probes used and
their weights, dropped ones, the LightProbe's coefficients, the normal and 8-bit sRGB pixel at
the canvas centre), without the canvas, which --screenshot writes as a PNG. With --serve it
only serves the interactive page and prints its address (open it in a browser; Ctrl-C stops).
"""

import argparse
import base64
import json
import os
import sys
import threading
import urllib.parse

import headless_three


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("baked")
    parser.add_argument("--at", required=True)
    parser.add_argument("--from", dest="camera")
    parser.add_argument("--rho")
    parser.add_argument("--radius")
    parser.add_argument("--size")
    parser.add_argument("--no-room", action="store_true")
    parser.add_argument("--screenshot")
    parser.add_argument("--serve", action="store_true")
    args = parser.parse_args()
    if not headless_three.available():
        print("probe-viewer-check: chromium or tools/.three missing (tools/install-three "
              "installs three; apt-get install chromium)", file=sys.stderr)
        sys.exit(2)
    folder, name = os.path.split(os.path.abspath(args.baked))
    query = {"bake": "/bake/" + name, "at": args.at, "post": "1"}
    for key, value in (("from", args.camera), ("rho", args.rho), ("radius", args.radius),
                       ("size", args.size)):
        if value is not None:
            query[key] = value
    if args.no_room:
        query["room"] = "0"

    def routes(path):
        if path in ("/probe-viewer.html", "/probe-viewer.js"):
            return os.path.join(headless_three.TOOLS, path[1:])
        if path.startswith("/bake/"):
            return os.path.join(folder, path[len("/bake/"):])
        return None

    if args.serve:
        del query["post"]
        server = headless_three.serve(routes, lambda body: None)
        print(f"http://127.0.0.1:{server.server_address[1]}/probe-viewer.html?"
              + urllib.parse.urlencode(query), flush=True)
        try:
            threading.Event().wait()
        except KeyboardInterrupt:
            return
    result = headless_three.run_page(
        routes, "/probe-viewer.html?" + urllib.parse.urlencode(query))
    png = result.pop("png", None)
    if args.screenshot and png:
        with open(args.screenshot, "wb") as f:
            f.write(base64.b64decode(png.split(",", 1)[1]))
    result["file"] = args.baked
    print("PROBE_VIEWER " + json.dumps(result, sort_keys=True))
    if "error" in result:
        sys.exit(1)


main()
