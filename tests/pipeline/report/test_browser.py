"""The report in a real browser: headless Chromium (Debian package ``chromium``) loads report.html, every figure
decodes, and the answer box sits above the fold of a 1280 x 800 window."""
from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from pipeline.cli import main

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")

PROBE = """<script>
window.addEventListener('load', function () {
  var imgs = Array.from(document.images);
  var broken = imgs.filter(function (i) { return !(i.complete && i.naturalWidth > 0); })
                   .map(function (i) { return i.alt || i.src.slice(0, 60); });
  var h = Array.from(document.querySelectorAll('h2')).find(function (e) { return e.textContent.trim() === 'Answer'; });
  var pre = document.createElement('pre');
  pre.id = 'vibro-check';
  pre.textContent = JSON.stringify({n_images: imgs.length, broken: broken, viewport: window.innerHeight,
                                    answer_top: h ? h.getBoundingClientRect().top : null,
                                    first_heading: document.querySelector('h2') ? document.querySelector('h2').textContent : null});
  document.body.appendChild(pre);
});
</script>"""


def _browse(html: Path) -> dict:
    """What the probe script saw in headless Chromium."""
    probe = html.with_name("browser-check.html")
    probe.write_text(html.read_text().replace("</body>", PROBE + "</body>"))
    dom = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--window-size=1280,800",
                          "--virtual-time-budget=10000", "--dump-dom", probe.as_uri()],
                         capture_output=True, text=True, timeout=120).stdout
    start = dom.index('<pre id="vibro-check">') + len('<pre id="vibro-check">')
    return json.loads(dom[start:dom.index("</pre>", start)].replace("&quot;", '"'))


@pytest.mark.skipif(CHROMIUM is None, reason="Chromium not installed (Debian package 'chromium'; .ci/run installs it)")
def test_report_loads_every_figure_decodes_and_the_answer_is_above_the_fold(tmp_path: Path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    rec = {"params": {"frequency_hz": 210.0, "amplitude_n": 2700.0, "static_force_n": 1800.0}, "rop_m_s_sim": 7.19e-3,
           "power_w_sim": 17.7, "binding": ["power_w 17.68 of its limit 18"]}
    (tmp_path / "results/optimise/rop").mkdir(parents=True)
    (tmp_path / "results/optimise/rop/report.json").write_text(json.dumps({"recommendation": rec}))
    (tmp_path / "results/diagnose/rig").mkdir(parents=True)
    shutil.copy(Path(__file__).parents[1] / "diagnosis/data/report_single.json",    # a stored diagnosis of a drill
                tmp_path / "results/diagnose/rig/report.json")
    assert main(["report", "--out", "results/report", "--no-mlflow"]) == 0, capsys.readouterr().err
    html = tmp_path / "results/report/report.html"
    seen = _browse(html)
    assert seen["first_heading"] == "Answer"
    assert seen["n_images"] >= 1 and seen["n_images"] == html.read_text().count("<img") and seen["broken"] == []
    assert seen["answer_top"] is not None and 0 <= seen["answer_top"] < 0.5 * seen["viewport"]
