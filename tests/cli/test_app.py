"""Issue 21 (items 1, 5, 6, 8-14) and issue 18 item 4 on the command line.

One place turns known errors into one line (exit 2), input bytes never reach the terminal
raw, parameters are bounded, outputs are named as given, evaluate commands share their input
options, batch checks before writing, the set-up works as README says, the first compile is
announced, tables keep file names whole at 80 columns, and ``--help`` is instant.
"""

from __future__ import annotations

import ast
import os
import socket
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import typer.main
from typer.testing import CliRunner

from conftest import cache_answers, real_file
from laser_corners.cli import app

runner = CliRunner()
CLI = [str(Path(sys.executable).with_name("laser-corners"))]
ROOT = Path(__file__).resolve().parents[2]
CLI_SRC = ROOT / "src" / "laser_corners" / "cli"


def _invoke(*args: str | Path):
    return runner.invoke(app, [str(a) for a in args])


def _one_line_error(result, *needles: str) -> str:
    assert result.exit_code == 2, (result.exit_code, result.output, result.exception)
    assert "Traceback" not in result.output
    # the one-time "compiling the detector's kernels" notice (cold numba cache) may come first
    lines = [
        line
        for line in result.stderr.strip().splitlines()
        if not line.startswith("laser-corners: compiling")
    ]
    assert len(lines) == 1 and lines[0].startswith("laser-corners: error: "), result.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


def _room_log(path: Path, n: int = 5) -> Path:
    """A CARMEN log of ``n`` 181-beam scans of a 6 m x 4 m room (written here)."""
    angles = np.linspace(-np.pi / 2, np.pi / 2, 181)
    along_x = 3.0 / np.maximum(np.abs(np.cos(angles)), 1e-9)
    along_y = 2.0 / np.maximum(np.abs(np.sin(angles)), 1e-9)
    body = " ".join(f"{r:.3f}" for r in np.minimum(along_x, along_y))
    lines = [f"FLASER 181 {body} 0 0 0 0 0 0 {i * 0.1:.3f} host {i * 0.1:.3f}" for i in range(n)]
    path.write_text("\n".join(lines) + "\n")
    return path


def _closed_port() -> int:
    """A port on 127.0.0.1 that nothing listens on (bound, then released)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


# ------------------------------------------------------------------ (1) tracebacks -> one line
def test_plot_to_an_unsupported_image_suffix_names_the_allowed_ones(tmp_path: Path) -> None:
    log = _room_log(tmp_path / "room.clf")
    line = _one_line_error(_invoke("plot", log, "-o", tmp_path / "k.xyz"), "'.xyz'", "--output")
    assert ".png" in line and ".pdf" in line and ".svg" in line
    assert not (tmp_path / "k.xyz").exists()


def test_demo_to_an_unsupported_image_suffix_is_one_line(tmp_path: Path) -> None:
    _one_line_error(_invoke("demo", "--output", tmp_path / "k.xyz"), "'.xyz'", ".png")


def test_plot_into_an_unwritable_place_is_one_line(tmp_path: Path) -> None:
    log = _room_log(tmp_path / "room.clf")
    _one_line_error(_invoke("plot", log, "-o", "/proc/k.png"), "/proc/k.png")


def test_view_save_onto_a_folder_is_one_line(tmp_path: Path) -> None:
    pytest.importorskip("rerun")
    log = _room_log(tmp_path / "room.clf")
    folder = tmp_path / "d"
    folder.mkdir()
    _one_line_error(_invoke("view", log, "--save", folder), "is a folder", "--save")


def test_known_errors_become_one_line_in_one_place() -> None:
    # issue 18 item 4: no command catches LaserCornersError itself; ErrorLineGroup does
    catching = []
    for path in sorted(CLI_SRC.glob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ExceptHandler) and "LaserCornersError" in ast.dump(node):
                catching.append(f"{path.name}:{node.lineno}")
            if isinstance(node, ast.With) and "known_errors" in ast.dump(node):
                catching.append(f"{path.name}:{node.lineno} with known_errors()")
    assert not catching, catching
    from laser_corners.cli.app import ErrorLineGroup

    assert isinstance(typer.main.get_command(app), ErrorLineGroup)


def test_an_unexpected_error_keeps_its_traceback(monkeypatch: pytest.MonkeyPatch) -> None:
    import laser_corners.params

    def broken(self, assignments):  # type: ignore[no-untyped-def]
        raise KeyError("a bug")

    monkeypatch.setattr(laser_corners.params.DetectorParams, "with_overrides", broken)
    result = _invoke("params", "--set", "min_points=6")
    assert result.exit_code == 1 and isinstance(result.exception, KeyError)


# ------------------------------------------------------------------ (5) bounded parameters
@pytest.mark.parametrize(
    ("override", "field", "bound"),
    [
        ("min_points=9223372036854775807", "min_points", "[2, 10000]"),
        ("min_points=1e20", "min_points", "[2, 10000]"),
        ("merge_radius=1e300", "merge_radius", "[0, 100]"),
        ("max_gap_beams=1e6", "max_gap_beams", "[0, 1000]"),
        ("scales=1e9,2e9,3e9", "scales", "(0, 100]"),
        ("refine_radius=1e9", "refine_radius", "[0, 100]"),
        ("max_point_distance=inf", "max_point_distance", "[0, 100]"),
    ],
)
def test_out_of_range_parameters_name_the_field_and_the_range(
    override: str, field: str, bound: str
) -> None:
    _one_line_error(_invoke("params", "--set", override), field, bound)


def test_every_numeric_parameter_has_a_range() -> None:
    from laser_corners import DetectorParams
    from laser_corners.params import _BOUNDS

    numeric = {
        name
        for name, info in DetectorParams.model_fields.items()
        if info.annotation in (int, float, "int", "float")
    }
    assert numeric and numeric <= set(_BOUNDS), numeric - set(_BOUNDS)


@pytest.mark.parametrize(
    ("name", "topic"),
    [
        ("fr079.bag", None),
        ("aces.bag", None),
        ("intel.bag", None),
        ("fr079-corrected.clf.gz", None),
        ("intel-corrected.clf.gz", None),
        ("hokuyo270_rooms.bag", "/left_scan"),
    ],
)
def test_presets_stay_within_the_bounds_on_real_scans(name: str, topic: str | None) -> None:
    from laser_corners.io import open_scans
    from laser_corners.presets import PRESETS, get_preset

    source = open_scans(real_file(name), topic=topic)
    scans = [s for _, s in zip(range(20), source, strict=False)]
    for preset in PRESETS:
        for scan in scans:
            get_preset(preset, scan)  # raises InvalidParamsError if a bound is crossed


def test_presets_stay_within_the_bounds_on_every_simulated_sensor() -> None:
    from laser_corners.presets import PRESETS, get_preset
    from laser_corners.sim import SENSORS, random_world

    rng = np.random.default_rng(3)
    world = random_world(rng, "room")
    for profile in SENSORS.values():
        for sigma in (0.0, profile.range_noise_sigma, 0.05):
            scan = world.scan((0.0, 0.0, 0.0), profile, noise_sigma=sigma, rng=rng)
            for preset in PRESETS:
                get_preset(preset, scan)


# ------------------------------------------------------------------ (6) input bytes escaped
def test_control_characters_from_a_file_never_reach_the_terminal(tmp_path: Path) -> None:
    log = tmp_path / "e.clf"
    log.write_bytes(b"\x1b]0;PWNED\x07 1 2\n")
    process = subprocess.run([*CLI, "detect", str(log)], capture_output=True, timeout=300)
    assert process.returncode == 2
    for stream in (process.stdout, process.stderr):
        assert b"\x1b" not in stream and b"\x07" not in stream
    assert b"\\x1b]0;PWNED\\x07" in process.stderr  # quoted, escaped


def test_error_line_escapes_c0_and_c1_controls_and_keeps_printable_text() -> None:
    from laser_corners.cli.app import error_line
    from laser_corners.errors import InputError

    line = error_line(InputError("f.clf: line 2: \x1b[31mred\x9b\x00 σ …\nnext"))
    assert line == "f.clf: line 2: \\x1b[31mred\\x9b\\x00 σ … next"


# ------------------------------------------------------------------ (8) names as given
def test_plot_without_a_suffix_writes_exactly_that_name(tmp_path: Path) -> None:
    log = _room_log(tmp_path / "room.clf")
    result = _invoke("plot", log, "-o", tmp_path / "name")
    assert result.exit_code == 0, result.output
    assert f"wrote {tmp_path / 'name'} " in result.stdout
    assert (tmp_path / "name").read_bytes()[:4] == b"\x89PNG"
    assert not (tmp_path / "name.png").exists()


def test_demo_without_a_suffix_writes_exactly_that_name(tmp_path: Path) -> None:
    result = _invoke("demo", "-o", tmp_path / "picture")
    assert result.exit_code in (0, 1), result.output
    assert (tmp_path / "picture").read_bytes()[:4] == b"\x89PNG"
    assert not (tmp_path / "picture.png").exists()


@pytest.mark.parametrize("command", ["real", "loops"])
def test_evaluate_errors_leave_no_empty_output_folder(tmp_path: Path, command: str) -> None:
    empty = tmp_path / "empty.clf"
    empty.write_text("# no scans\n")
    out = tmp_path / "new" / "report"
    result = _invoke("evaluate", command, empty, "-o", out)
    assert result.exit_code == 2, result.output
    last = result.stderr.strip().splitlines()[-1]  # loops says its phase first
    assert last.startswith("laser-corners: error: ") and "empty.clf" in last
    assert not (tmp_path / "new").exists()
    kept = tmp_path / "kept"
    kept.mkdir()  # a folder that was there before stays
    assert _invoke("evaluate", command, empty, "-o", kept).exit_code == 2
    assert kept.is_dir()


# ------------------------------------------------------------------ (9) loops: progress, odometry
def test_loops_shows_its_phases_from_the_start_and_warns_about_odometry(tmp_path: Path) -> None:
    bag = real_file("intel.bag")
    out = tmp_path / "L"
    process = subprocess.Popen(
        [
            *CLI,
            "evaluate",
            "loops",
            str(bag),
            "-o",
            str(out),
            "--max-scans",
            "12",
            "--methods",
            "paper",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        first = process.stderr.readline()  # type: ignore[union-attr]
        _, rest = process.communicate(timeout=900)
    finally:
        process.kill()  # a failed assertion or a timeout leaves no process behind
    assert first.startswith("reading intel.bag"), first  # said before the (long) reading
    assert process.returncode == 0, rest
    lines = [first, *rest.splitlines()]
    warnings = [line for line in lines if line.startswith("warning:")]
    assert len(warnings) == 1 and "odometry" in warnings[0] and "--trajectory" in warnings[0]
    for phase in ("revisits", "paper: detecting", "paper: matching"):
        assert any(line.startswith(phase) for line in lines), (phase, lines)
    assert (out / "loops.json").exists()


def test_loops_on_corrected_poses_does_not_warn(tmp_path: Path) -> None:
    log = _room_log(tmp_path / "room.clf", n=6)
    result = _invoke("evaluate", "loops", log, "-o", tmp_path / "L", "--methods", "paper")
    assert result.exit_code == 0, result.output
    assert "warning" not in result.stderr


# ------------------------------------------------------------------ (10) same input options
def _evaluate_commands() -> dict[str, object]:
    group = typer.main.get_command(app)
    return dict(group.commands["evaluate"].commands)  # type: ignore[attr-defined]


def test_every_evaluate_command_on_a_recording_takes_the_same_input_options() -> None:
    input_options = {"--topic", "--trajectory", "--max-scans"}
    readers = 0
    for name, command in _evaluate_commands().items():
        params = command.params  # type: ignore[attr-defined]
        if not any(p.name == "input_path" for p in params):
            continue
        readers += 1
        options = {o for p in params for o in getattr(p, "opts", [])}
        assert input_options <= options, (name, input_options - options)
    assert readers >= 2


def test_errors_suggest_only_options_the_command_has(tmp_path: Path) -> None:
    import re

    bag = real_file("hokuyo270_rooms.bag")
    result = _invoke("evaluate", "loops", bag, "-o", tmp_path / "L")
    assert result.exit_code == 2
    assert "--topic /left_scan" in result.stderr
    loops = _evaluate_commands()["loops"]
    options = {o for p in loops.params for o in getattr(p, "opts", [])}  # type: ignore[attr-defined]
    suggested = set(re.findall(r"--[a-z][a-z-]+", result.stderr))
    assert suggested and suggested <= options, suggested - options
    # no pose: the message asks for a trajectory, which loops takes
    result = _invoke("evaluate", "loops", bag, "--topic", "/left_scan", "-o", tmp_path / "L")
    if result.exit_code == 2 and "trajectory" in result.stderr:
        assert "--trajectory" in options


# ------------------------------------------------------------------ (11) batch checks first
def test_batch_with_an_unreachable_scheduler_writes_nothing(tmp_path: Path) -> None:
    pytest.importorskip("distributed")
    log = _room_log(tmp_path / "room.clf")
    out = tmp_path / "corners"
    port = _closed_port()
    scheduler = f"tcp://127.0.0.1:{port}"
    _one_line_error(_invoke("batch", log, "-o", out, "--scheduler", scheduler), scheduler)
    assert not out.exists()


def test_batch_with_a_glob_that_matches_nothing_names_it_and_writes_nothing(
    tmp_path: Path,
) -> None:
    log = _room_log(tmp_path / "room.clf")
    pattern = str(tmp_path / "fleet" / "*.bag")
    out = tmp_path / "corners"
    _one_line_error(_invoke("batch", log, pattern, "-o", out), pattern, "no file matches")
    assert not out.exists()


# ------------------------------------------------------------------ (12) set-up as README says
def test_version_and_evaluate_help_list_every_subcommand() -> None:
    from laser_corners import __version__

    version = subprocess.run([*CLI, "--version"], capture_output=True, text=True, timeout=120)
    assert version.returncode == 0 and version.stdout.strip() == f"laser-corners {__version__}"
    result = _invoke("evaluate", "--help")
    assert result.exit_code == 0
    for name in _evaluate_commands():
        assert name in result.stdout
    assert "loops" in result.stdout.split("Commands")[0]  # named in the group's own help too


def test_readme_set_up_says_where_the_command_is_and_installs_from_the_checkout() -> None:
    readme = (ROOT / "README.md").read_text()
    assert ".venv/bin/laser-corners" in readme and "source .venv/bin/activate" in readme
    assert "pip install 'laser-corners[" not in readme  # not on PyPI
    assert "pip install '.[ros2]'" in readme and "laser-corners --version" in readme
    assert "several seconds" not in readme and "26-35 s" in readme


# ------------------------------------------------------------------ (13) first compile announced
def test_kernel_cache_check_tells_cold_from_warm(tmp_path: Path) -> None:
    from laser_corners import CornerDetector, LaserScan

    CornerDetector().detect(LaserScan(np.full(64, 2.0), -0.5, 0.01, 0.05, 10.0))  # warm
    check = "from laser_corners.cli.kernels import kernels_are_cold; print(kernels_are_cold())"
    warm, cold = cache_answers(check, tmp_path)
    assert warm.stdout.strip() == "False", warm.stderr
    assert cold.stdout.strip() == "True", cold.stderr


def test_detecting_commands_announce_a_cold_cache_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import laser_corners.cli.kernels as kernels

    log = _room_log(tmp_path / "room.clf")
    monkeypatch.setattr(kernels, "kernels_are_cold", lambda: True)
    result = _invoke("detect", log)
    assert result.exit_code == 0, result.output
    assert result.stderr.count(kernels.COMPILING) == 1
    monkeypatch.setattr(kernels, "kernels_are_cold", lambda: False)
    result = _invoke("detect", log)
    assert kernels.COMPILING not in result.stderr
    assert "warmup" in (ROOT / "Makefile").read_text()


def test_warmup_compiles_the_kernels() -> None:
    result = _invoke("warmup")
    assert result.exit_code == 0, result.output
    assert "kernels ready in" in result.stdout


# ------------------------------------------------------------------ (14) 80 columns
def test_tables_at_80_columns_keep_file_names_whole(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("COLUMNS", "80")
    monkeypatch.chdir(tmp_path)
    name = "hokuyo270_rooms_left_scan_recording"
    _room_log(Path(f"{name}.clf"))
    result = _invoke("batch", f"{name}.clf", "-o", "out", "--workers", "1")
    assert result.exit_code == 0, result.output
    assert name in result.stdout and "…" not in result.stdout
    result = _invoke("detect", f"{name}.clf")
    assert result.exit_code == 0, result.output
    assert f"{name}.clf" in result.stdout.splitlines()[0]  # the title on one line


def test_errors_off_a_terminal_start_with_the_error() -> None:
    process = subprocess.run(
        [*CLI, "detect", "no-such-file.bag"], capture_output=True, text=True, timeout=120
    )
    assert process.returncode == 2
    assert process.stderr.startswith("laser-corners: error: no-such-file.bag"), process.stderr


# ------------------------------------------------------------------ issue 18: lazy package
def test_help_loads_no_numerics() -> None:
    code = (
        "import sys\nsys.argv = ['laser-corners', '--help']\nfrom laser_corners.cli import main\n"
        "try:\n    main()\nexcept SystemExit:\n    pass\n"
        "print(sorted(m for m in ('numpy', 'numba', 'scipy', 'matplotlib', 'pydantic', "
        "'yaml', 'rich.progress', 'typer.rich_utils', 'rich.markdown') "
        "if m in sys.modules), file=sys.stderr)"
    )
    process = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120
    )
    assert process.stderr.strip() == "[]", process.stderr


def _median_seconds(argv: list[str], runs: int = 5) -> float:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        subprocess.run(argv, capture_output=True, check=True, timeout=120)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def test_help_answers_at_once() -> None:
    # median of 5 after a warm-up run: under 0.5 s on an idle machine (0.26-0.33 s measured).
    # The help is click's plain one: typer's rich help alone (typer.rich_utils, rich.markdown)
    # took 0.35-0.45 s here. On a loaded machine every start-up slows down, so the limit grows
    # with the floor (Python starting with typer): at most twice that.
    subprocess.run([*CLI, "--help"], capture_output=True, check=True, timeout=120)
    help_seconds = _median_seconds([*CLI, "--help"])
    floor = _median_seconds([sys.executable, "-c", "import typer"])
    assert help_seconds < max(0.5, 2.0 * floor), (help_seconds, floor)


def test_a_stale_kernel_of_another_room_does_not_say_compiling(tmp_path: Path) -> None:
    # after an upgrade, a matching kernel that has not run again keeps a stale index: the
    # detector's kernels are warm, so a detecting command must not say it compiles
    script = """
import shutil
from numba.core.dispatcher import Dispatcher
import numpy as np
from laser_corners import CornerDetector, LaserScan
import laser_corners.matching.core as other
from laser_corners.kernel import candidates
from laser_corners.cli.kernels import kernels_are_cold

CornerDetector().detect(LaserScan(np.full(64, 2.0), -0.5, 0.01, 0.05, 10.0))
def own_kernels(module):
    return [o for o in vars(module).values()
            if isinstance(o, Dispatcher) and o.py_func.__module__ == module.__name__]
warm = own_kernels(candidates)[0]
kernel = own_kernels(other)[0]
stale = kernel._cache._cache_file._index_path
shutil.copyfile(warm._cache._cache_file._index_path, stale)  # another source's stamp
assert not kernel._cache._cache_file._load_index()  # stale indeed
print(kernels_are_cold())
"""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    run = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=600
    )
    assert run.stdout.strip() == "False", run.stderr
