#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""`bench/scene_corpus.py` on a folder written here: which files are scenes, and how each ends.

The folder holds a scene that renders (8x8 pixels, 4 spp), one that includes a fragment from a
subfolder found through its <path> tag (the fragment is a part, not a scene), one whose include
names its file through a parameter, a fragment without a sensor that nothing includes, one with a
participating medium (out of scope: listed with its plugin), one with a misspelt BSDF (an
error, with gdmlt's message) and an XML file that is not a scene. No Mitsuba: --compare is not
run. About 1 s.

    GDMLT_BINARY=build/release/gdmlt tests/bench/test_scene_corpus.py
"""
import json
import os
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

HEAD = """<scene version="3.0.0">
    <sensor type="perspective"><float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
    </sensor>
    <emitter type="constant"><rgb name="radiance" value="0.5"/></emitter>
"""
FILES = {
    "plain.xml": HEAD + '    <shape type="sphere"><bsdf type="diffuse"/></shape>\n</scene>\n',
    "with_part.xml": HEAD + '    <path value="parts"/>\n    <include filename="ball.xml"/>\n</scene>\n',
    "parts/ball.xml": '<scene version="3.0.0">\n    <shape type="sphere"><bsdf type="roughplastic"/>'
                      '</shape>\n</scene>\n',
    "smoke.xml": HEAD + '    <shape type="sphere"><bsdf type="diffuse"/>\n'
                        '        <medium name="interior" type="homogeneous"/></shape>\n</scene>\n',
    "typo.xml": HEAD + '    <shape type="sphere"><bsdf type="difuse"/></shape>\n</scene>\n',
    "not_a_scene.xml": '<bsdf type="diffuse"/>\n',
    # Includes named through a parameter (Mitsuba's cbox.xml: fragments/bsdfs-$variant.xml):
    # every file the name can match is a part, though each holds a sensor.
    "with_parameter.xml": '<scene version="3.0.0">\n    <default name="view" value="near"/>\n'
                          '    <include filename="parts/view_$view.xml"/>\n'
                          '    <shape type="sphere"/>\n</scene>\n',
    "parts/view_near.xml": HEAD + '</scene>\n',
    "parts/view_far.xml": HEAD.replace("0, 0, 4", "0, 0, 8") + '</scene>\n',
    # No sensor of its own or through includes: a fragment nobody includes, not a scene.
    "loose_part.xml": '<scene version="3.0.0">\n    <shape type="sphere"/>\n</scene>\n',
}


class SceneCorpus(unittest.TestCase):
    def test_every_stand_alone_scene_is_rendered_or_says_why_not(self):
        binary = os.environ.get("GDMLT_BINARY", os.path.join(ROOT, "build", "release", "gdmlt"))
        with tempfile.TemporaryDirectory(prefix="gdmlt_scene_corpus_test_") as tmp:
            corpus = os.path.join(tmp, "corpus")
            for name, text in FILES.items():
                path = os.path.join(corpus, name)
                os.makedirs(os.path.dirname(path), exist_ok=True)
                with open(path, "w") as f:
                    f.write(text)
            out = os.path.join(tmp, "out")
            run = subprocess.run(
                [sys.executable, os.path.join(ROOT, "bench", "scene_corpus.py"), corpus,
                 "--binary", binary, "--spp", "4", "--threads", "2", "--out", out],
                capture_output=True, text=True, timeout=300)
            self.assertEqual(run.returncode, 0, run.stdout + run.stderr)
            with open(os.path.join(out, "scene_corpus.json")) as f:
                report = json.load(f)
            by_scene = {r["scene"]: r for r in report["scenes"]}
            self.assertEqual(sorted(by_scene), ["plain.xml", "smoke.xml", "typo.xml",
                                                "with_parameter.xml", "with_part.xml"], run.stdout)
            self.assertEqual(by_scene["with_parameter.xml"]["status"], "renders")
            self.assertEqual(by_scene["plain.xml"]["status"], "renders")
            self.assertEqual(by_scene["with_part.xml"]["status"], "renders")
            self.assertTrue(os.path.isfile(os.path.join(out, "with_part.gdmlt.0.exr")))
            self.assertEqual(by_scene["smoke.xml"]["status"], "out of scope")
            self.assertEqual(by_scene["smoke.xml"]["plugin"], "medium homogeneous")
            self.assertEqual(by_scene["typo.xml"]["status"], "error")
            self.assertIn("difuse", by_scene["typo.xml"]["message"])
            self.assertEqual(report["counts"], {"renders": 3, "out of scope": 1, "error": 1})
            with open(os.path.join(out, "scene_corpus.md")) as f:
                table = f.read()
            self.assertIn("5 stand-alone (5 parts left out), 3 render, 1 out of scope, 1 errors",
                          table)


if __name__ == "__main__":
    unittest.main()
