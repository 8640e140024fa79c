"""The README's two commands exist, do their own set-up, and CI runs the test command."""

import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _readme_commands():
    text = (REPO / "README.md").read_text(encoding="utf-8")
    # Indented code lines in "The two commands" section are the commands.
    section = text.split("## The two commands", 1)[1].split("\n## ", 1)[0]
    return [line.strip() for line in section.splitlines() if re.match(r"^ {4}\S", line)]


def test_readme_names_two_commands_that_exist():
    commands = _readme_commands()
    assert commands == ["tools/run-demo", "tools/run-tests"]
    for command in commands:
        script = REPO / command
        assert script.is_file() and script.stat().st_mode & 0o111, command
        assert "tools/setup-env" in script.read_text(), f"{command} must do its own set-up"


def test_ci_runs_the_readme_test_command():
    ci = (REPO / ".ci" / "run").read_text()
    assert re.search(r"^exec bash tools/run-tests\s*$", ci, re.MULTILINE)


def test_bad_command_line_is_one_line_and_exit_2():
    result = subprocess.run([sys.executable, "-m", "vsgl_addon", "no-such-command"], cwd=REPO,
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr


def test_main_job_renders_the_demo_and_says_where_the_images_are(tmp_path):
    out = tmp_path / "demo.exr"
    result = subprocess.run([sys.executable, "-m", "vsgl_addon", "demo", "--out", str(out), "--resolution", "64x48"],
                            cwd=REPO, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    version = re.search(r'^version = "(.+)"$', (REPO / "blender_manifest.toml").read_text(), re.MULTILINE)[1]
    assert f"VSGL add-on {version}: rendering demo.blend" in result.stdout
    assert "GPU llvmpipe" in result.stdout and "vsgl_shading" in result.stdout
    assert f"images: {out}" in result.stdout and f"report: {out.with_suffix('.json')}" in result.stdout
    assert out.is_file() and out.with_suffix(".png").is_file() and out.with_suffix(".json").is_file()
