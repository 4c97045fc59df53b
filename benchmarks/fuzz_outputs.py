"""Output paths that would destroy an input, and the 25000 x 25000 frame (issue 26).

Every command that writes is called with an output path that is one of its inputs (also through
a symbolic link, or a file the experiment inherits), a capture's ``manifest.csv``,
``camera.yaml`` or image, a path inside a bag, a FIFO (standing for ``/dev/null``: no case touches
``/dev``), a folder where a file goes and a file where a folder goes, or a user's file or folder.
Each must be refused before any work: exit code 2, one line naming the option and the path, no
traceback, and every file of the scenario byte-identical afterwards with nothing written (the
commands' caches are inside the scenario, so a render would show).

:func:`big_frame_peaks` measures the peak memory of refusing a 600 KB PNG of 25000 x 25000 px
(its pixels would take 625 MB grey and 1.9 GB decoded as colour): the peak resident memory of
a whole ``simgap ingest`` process that meets it, beside the same command on frames of the
calibration's size.

``benchmarks/fuzz_inputs.py`` prints these cases as its ``outputs`` family, and
``tests/test_outputs.py`` runs each one. Alone::

    python benchmarks/fuzz_outputs.py
"""

from __future__ import annotations

import hashlib
import math
import os
import stat
import struct
import subprocess
import sys
import tempfile
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from simgap.cli.outputs import OUTPUT
from simgap.core.rig import CameraModel, load_rig
from simgap.pipeline.bag import capture_to_bag
from simgap.pipeline.capture import calibration_to_yaml, ingest, write_capture
from simgap.results.dataset import write_netcdf

SMALL = CameraModel(64, 48, 60.0, 60.0, 31.5, 23.5)
#: The frame of issue 26: 25000 x 25000 px, about 600 KB as a grey PNG.
BIG_SIDE_PX = 25000
#: The memory target of refusing it (MB, issue 26).
BIG_FRAME_TARGET_MB = 300


@dataclass(frozen=True)
class Scenario:
    """The files every output case reads or aims at, all under ``root``."""

    root: Path
    experiment: Path  # inherits ``parent``
    parent: Path
    result: Path  # the capture's result dataset (simgap ingest)
    capture: Path  # camera.yaml, manifest.csv, images/
    bag1: Path  # ROS 1 .bag exported from the capture
    bag2: Path  # ROS 2 bag folder exported from the capture
    fifo: Path
    folder: Path  # a user's folder holding a user's file
    user_file: Path  # a file simgap did not write
    user_json: Path  # a JSON file simgap did not write, beside where a model's .json would go
    cache: Path

    def link(self, name: str, target: Path) -> Path:
        """A symbolic link ``root/name`` to ``target`` (made once)."""
        path = self.root / name
        if not path.is_symlink():
            path.symlink_to(target)
        return path


def make_scenario(root: Path) -> Scenario:
    """Write the scenario's inputs (a second call on the same root reuses them)."""
    root.mkdir(parents=True, exist_ok=True)
    s = Scenario(
        root,
        root / "exp.yaml",
        root / "parent.yaml",
        root / "result.nc",
        root / "capture",
        root / "capture.bag",
        root / "capture_ros2",
        root / "fifo",
        root / "user_folder",
        root / "notes.txt",
        root / "model.json",
        root / "cache",
    )
    if s.experiment.is_file():
        return s
    s.parent.write_text("name: parent\nconfigurations: {p: [7], theta_deg: [0, 30]}\n")
    s.experiment.write_text("name: child\ninherit: parent.yaml\nrender: {spp: 4}\n")
    img = np.full((SMALL.height, SMALL.width, 3), 200, np.uint8)
    write_capture(s.capture, [(0, 0.0, 0, img), (7, math.radians(30), 0, img)], SMALL)
    write_netcdf(ingest(s.capture), s.result)  # a result dataset as simgap writes it
    capture_to_bag(s.capture, s.bag1, "ros1")
    capture_to_bag(s.capture, s.bag2, "ros2")
    os.mkfifo(s.fifo)
    s.folder.mkdir()
    (s.folder / "thesis.tex").write_text("\\chapter{Results}\n")
    s.user_file.write_text("my notes\n")
    s.user_json.write_text('{"mine": true}\n')
    return s


#: label -> what the case runs: ``(argv, option the message names, path it names)``.
OutputCase = Callable[[Scenario], tuple[list[str], str, Path]]


def _argv(s: Scenario, parts: list) -> list[str]:
    """``parts`` with scenario attribute names (``"@capture"``) replaced by their paths."""
    out = []
    for part in parts:
        if isinstance(part, str) and part.startswith("@"):
            name, _, rel = part[1:].partition("/")
            path = getattr(s, name)
            part = str(path / rel if rel else path)
        out.append(str(part))
    return out


def _case(command: list, target: str, option: str = OUTPUT, flag: str = "-o") -> OutputCase:
    """A case whose target is a scenario path (``"@capture/manifest.csv"``) or a link."""

    def make(s: Scenario) -> tuple[list[str], str, Path]:
        if target.startswith("link:"):  # link:NAME:@TARGET
            _, name, to = target.split(":", 2)
            path = s.link(name, Path(_argv(s, [to])[0]))
        else:
            path = Path(_argv(s, [target])[0])
        return _argv(s, command) + [flag, str(path)], option, path

    return make


RUN = ["run", "@experiment", "--cache", "@cache", "--no-progress"]
STUDY = ["study", "@experiment", "--cache", "@cache"]
REPORT = ["report", "@result"]
COMPARE = ["compare", "@result"]
DIAGNOSE = ["diagnose", "@result", "--sim", "@experiment", "--cache", "@cache"]
VALIDATE = ["validate", "--trials", "1", "--experiment", "@experiment", "--cache", "@cache"]
INGEST = ["ingest", "@capture", "--no-progress"]
INGEST_BAG = ["ingest", "@bag1", "--no-progress"]
ERRORMODEL = ["errormodel", "@result"]
EXPORT = ["export-bag", "@capture"]
FRESH = "@root/fresh.nc"

OUTPUT_CASES: dict[str, OutputCase] = {
    # the command's own input, directly, through a link, or a file it inherits
    "run -o its experiment": _case(RUN, "@experiment"),
    "run -o the experiment it inherits": _case(RUN, "@parent"),
    "run -o a link to its experiment": _case(RUN, "link:exp_link.yaml:@experiment"),
    "study -o its experiment": _case(STUDY, "@experiment"),
    "report -o its dataset": _case(REPORT, "@result"),
    "report -o a link to its dataset": _case(REPORT, "link:result_link.nc:@result"),
    "compare -o its dataset": _case(COMPARE, "@result"),
    "diagnose -o its real dataset": _case(DIAGNOSE, "@result"),
    "diagnose --json its experiment": _case(
        DIAGNOSE + ["-o", "@root/d"], "@experiment", "--json", "--json"
    ),
    "diagnose --json a link to its dataset": _case(
        DIAGNOSE + ["-o", "@root/d"], "link:real_link.nc:@result", "--json", "--json"
    ),
    "validate -o its experiment": _case(VALIDATE, "@experiment"),
    "ingest -o its capture folder": _case(INGEST, "@capture"),
    "ingest -o manifest.csv": _case(INGEST, "@capture/manifest.csv"),
    "ingest -o camera.yaml": _case(INGEST, "@capture/camera.yaml"),
    "ingest -o an image of the capture": _case(INGEST, "@capture/images/p00_t000.png"),
    "ingest -o a new file in the capture": _case(INGEST, "@capture/real.nc"),
    "ingest -o a link to manifest.csv": _case(
        INGEST, "link:manifest_link.csv:@capture/manifest.csv"
    ),
    "ingest -o its --experiment": _case(INGEST + ["--experiment", "@experiment"], "@experiment"),
    "ingest -o its ROS 1 bag": _case(INGEST_BAG, "@bag1"),
    "ingest -o inside its ROS 2 bag": _case(["ingest", "@bag2"], "@bag2/metadata.yaml"),
    "ingest --keep-capture a capture": _case(
        INGEST_BAG + ["-o", FRESH], "@capture", "--keep-capture", "--keep-capture"
    ),
    "ingest --keep-capture inside its bag": _case(
        ["ingest", "@bag2", "-o", FRESH], "@bag2/capture", "--keep-capture", "--keep-capture"
    ),
    "errormodel -o its dataset": _case(ERRORMODEL, "@result"),
    "errormodel -o a link to its dataset": _case(ERRORMODEL, "link:result_link.nc:@result"),
    "export-bag -o its capture (ROS 2)": _case(EXPORT, "@capture"),
    "export-bag -o manifest.csv (ROS 1)": _case(
        EXPORT + ["--format", "ros1"], "@capture/manifest.csv"
    ),
    "export-bag -o an image (ROS 1)": _case(
        EXPORT + ["--format", "ros1"], "@capture/images/p07_t030.png"
    ),
    "export-bag -o a folder holding the capture": _case(EXPORT, "@root"),
    "export-bag -o its experiment": _case(
        ["export-bag", "@experiment", "--format", "ros1"], "@experiment"
    ),
    "export-bag -o its dataset": _case(["export-bag", "@result", "--format", "ros1"], "@result"),
    "diagnose --json = its -o": _case(DIAGNOSE + ["-o", "@root/d"], "@root/d", "--json", "--json"),
    # devices: a FIFO stands for /dev/null
    "run -o FIFO": _case(RUN, "@fifo"),
    "study -o FIFO": _case(STUDY, "@fifo"),
    "report -o FIFO": _case(REPORT, "@fifo"),
    "compare -o FIFO": _case(COMPARE, "@fifo"),
    "diagnose -o FIFO": _case(DIAGNOSE, "@fifo"),
    "diagnose --json FIFO": _case(DIAGNOSE + ["-o", "@root/d"], "@fifo", "--json", "--json"),
    "validate -o FIFO": _case(VALIDATE, "@fifo"),
    "ingest -o FIFO": _case(INGEST, "@fifo"),
    "ingest --keep-capture FIFO": _case(
        INGEST_BAG + ["-o", FRESH], "@fifo", "--keep-capture", "--keep-capture"
    ),
    "errormodel -o FIFO": _case(ERRORMODEL, "@fifo"),
    "export-bag -o FIFO (ROS 1)": _case(EXPORT + ["--format", "ros1"], "@fifo"),
    "export-bag -o FIFO (ROS 2)": _case(EXPORT, "@fifo"),
    # a folder where a file goes
    "run -o a folder": _case(RUN, "@folder"),
    "ingest -o a folder": _case(INGEST, "@folder"),
    "errormodel -o a folder": _case(ERRORMODEL, "@folder"),
    "diagnose --json a folder": _case(DIAGNOSE + ["-o", "@root/d"], "@folder", "--json", "--json"),
    "export-bag -o a folder (ROS 1)": _case(EXPORT + ["--format", "ros1"], "@folder"),
    # a file where a folder goes
    "study -o a file": _case(STUDY, "@user_file"),
    "report -o a file": _case(REPORT, "@user_file"),
    "compare -o a file": _case(COMPARE, "@user_file"),
    "diagnose -o a file": _case(DIAGNOSE, "@user_file"),
    "validate -o a file": _case(VALIDATE, "@user_file"),
    "ingest --keep-capture a file": _case(
        INGEST_BAG + ["-o", FRESH], "@user_file", "--keep-capture", "--keep-capture"
    ),
    "export-bag -o a file (ROS 2)": _case(EXPORT + ["--format", "ros2"], "@user_file"),
    # a file or folder simgap did not write (needs --overwrite)
    "run -o a user's file": _case(RUN, "@user_file"),
    "run -o a below a user's file": _case(RUN, "@user_file/x.nc"),
    "ingest -o a user's file": _case(INGEST, "@user_file"),
    "errormodel -o beside a user's JSON": lambda s: (
        _argv(s, ERRORMODEL + ["-o", "@root/model.nc"]),
        f"{OUTPUT} (its .json)",
        s.user_json,
    ),
    "diagnose --json a user's JSON": _case(
        DIAGNOSE + ["-o", "@root/d"], "@user_json", "--json", "--json"
    ),
    "export-bag -o a user's file (ROS 1)": _case(EXPORT + ["--format", "ros1"], "@user_file"),
    "export-bag -o a user's folder (ROS 2)": _case(EXPORT, "@folder"),
    "report -o a user's folder": _case(REPORT, "@folder"),
    "compare -o a user's folder": _case(COMPARE, "@folder"),
    "diagnose -o a user's folder": _case(DIAGNOSE, "@folder"),
    "validate -o a user's folder": _case(VALIDATE, "@folder"),
}


def snapshot(root: Path) -> dict[str, str]:
    """Every entry under ``root``: a file's SHA-256, a link's target, another entry's type.

    Nothing is opened but regular files (a FIFO is never opened).
    """
    out = {}
    for folder, dirs, files in os.walk(root):
        for name in dirs + files:
            path = Path(folder, name)
            rel = str(path.relative_to(root))
            mode = path.lstat().st_mode
            if stat.S_ISLNK(mode):
                out[rel] = "link -> " + os.readlink(path)
            elif stat.S_ISREG(mode):
                out[rel] = hashlib.sha256(path.read_bytes()).hexdigest()
            else:
                out[rel] = "folder" if stat.S_ISDIR(mode) else f"mode {stat.S_IFMT(mode):o}"
    return out


def run_case(s: Scenario, case: OutputCase) -> tuple[str, str]:
    """Run one case through the command line: ``("named" | "raw" | "accepted", detail)``.

    Named: exit code 2, one line naming the option and the path, no traceback, and the
    scenario unchanged (every file byte-identical, nothing written).
    """
    from typer.testing import CliRunner

    from simgap.cli import app

    argv, option, path = case(s)
    before = snapshot(s.root)
    res = CliRunner().invoke(app, argv)
    after = snapshot(s.root)
    text = res.output.strip()
    lines = [line for line in text.splitlines() if line.strip()]
    changed = sorted(k for k in before.keys() | after.keys() if before.get(k) != after.get(k))
    if res.exit_code == 0:
        return "accepted", text[-200:]
    if changed:
        return "raw", f"changed {changed[:4]}: {text[-200:]}"
    if res.exit_code == 2 and len(lines) == 1 and "Traceback" not in text:
        if f"{option} {path}" in lines[0]:
            return "named", lines[0]
        return "raw", f"does not name {option} {path}: {lines[0]}"
    return "raw", f"exit {res.exit_code}: {text[-300:]}"


# --- the 25000 x 25000 frame ------------------------------------------------------------------


def big_png(path: Path, width: int = BIG_SIDE_PX, height: int = BIG_SIDE_PX) -> Path:
    """Write an all-black 8-bit grey PNG of ``width`` x ``height`` px, row by row.

    zlib compresses the rows as they come, so writing it needs a row's memory, not the
    image's; 25000 x 25000 px is about 600 KB.
    """

    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = zlib.crc32(kind + data)
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)

    packer = zlib.compressobj(9)
    row = b"\x00" * (width + 1)  # filter type 0, then the row's bytes
    idat = b"".join(packer.compress(row) for _ in range(height)) + packer.flush()
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)  # 8-bit grey
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")
    )
    return path


def jpeg_claiming(width: int, height: int) -> bytes:
    """A small JPEG whose start-of-frame segment says ``width`` x ``height`` px (a header-only lie:
    decoding it would allocate the claimed size before finding the data short)."""
    ok, buf = cv2.imencode(".jpg", np.full((48, 64, 3), 200, np.uint8))
    data = bytearray(buf.tobytes())
    sof = data.index(b"\xff\xc0")  # baseline SOF0: length (2), precision (1), height, width
    data[sof + 5 : sof + 9] = struct.pack(">HH", height, width)
    return bytes(data)


@dataclass(frozen=True)
class BigFramePeak:
    """Peak resident memory of one ``simgap ingest`` process (the whole process: interpreter,
    imports, work)."""

    label: str
    exit_code: int
    peak_mib: float
    message: str  # the line that names the frame


#: Runs ``simgap ARGV`` and, at exit, prints the process's peak resident memory (``VmHWM``, kB).
#: ``VmHWM`` belongs to the process's own memory map: unlike ``ru_maxrss``, which Linux carries
#: over ``fork`` and ``execve`` from the parent (this benchmark), it counts this process alone.
_PEAK_WRAPPER = (
    "import atexit, sys\n"
    "def peak():\n"
    "    status = open('/proc/self/status').read().split('VmHWM:')[1]\n"
    "    print('VmHWM', status.split()[0], file=sys.stderr)\n"
    "atexit.register(peak)\n"
    "from simgap.cli import app\n"
    "sys.argv[0] = 'simgap'\n"
    "app()\n"
)


def command_peak(argv: list[str]) -> tuple[int, float, str]:
    """Run ``simgap ARGV`` in a fresh interpreter: exit code, peak resident memory (MiB), and the
    last line that names an error or warning."""
    done = subprocess.run(
        [sys.executable, "-c", _PEAK_WRAPPER, *argv], capture_output=True, text=True
    )
    lines = [line.strip() for line in (done.stdout + done.stderr).splitlines() if line.strip()]
    peak_kb = next(int(line.split()[1]) for line in lines if line.startswith("VmHWM"))
    lines = [line for line in lines if not line.startswith("VmHWM")]
    said = [line for line in lines if "error" in line or "Warning" in line] or lines
    return done.returncode, peak_kb / 1024, said[-1]


def big_frame_peaks(tmp: Path) -> list[BigFramePeak]:
    """``simgap ingest`` of the 25000 x 25000 frame as a capture's first frame (an error), its
    second frame (a recorded failure) and a compressed bag's frame, and of the same capture with
    its own frames (the reference: what any ingest costs), each in a fresh process."""
    from simgap.pipeline.bag import BagFrame, write_bag

    png = big_png(tmp / "big.png")
    img = np.full((SMALL.height, SMALL.width, 3), 200, np.uint8)
    runs = {}
    for label, name, image in (
        ("reference: 64x48 frames", "reference", None),
        ("capture, first frame", "first", "p00_t000.png"),
        ("capture, second frame", "second", "p07_t030.png"),
    ):
        folder = tmp / name
        write_capture(folder, [(0, 0.0, 0, img), (7, math.radians(30), 0, img)], SMALL)
        if image is not None:
            (folder / "images" / image).write_bytes(png.read_bytes())
        runs[label] = ["ingest", str(folder), "-o", str(tmp / f"{name}.nc"), "--no-progress"]
    frames = [BagFrame(0, 0.0, 0, img), BagFrame(7, math.radians(30), 0, (png.read_bytes(), "png"))]
    bag = write_bag(tmp / "big.bag", "ros1", SMALL, frames, load_rig(), images="png")
    runs["compressed bag frame"] = ["ingest", str(bag), "-o", str(tmp / "bag.nc"), "--no-progress"]
    # the calibration vouches for the bomb: refused by the pixel budget (issue 51)
    vouching = CameraModel(BIG_SIDE_PX, BIG_SIDE_PX, 20000.0, 20000.0, 12499.5, 12499.5)
    folder = tmp / "vouched"
    write_capture(folder, [(0, 0.0, 0, img)], SMALL)
    (folder / "camera.yaml").write_text(calibration_to_yaml(vouching))
    (folder / "images" / "p00_t000.png").write_bytes(png.read_bytes())
    runs["capture whose camera.yaml states 25000x25000"] = [
        "ingest", str(folder), "-o", str(tmp / "vouched.nc"), "--no-progress",
    ]  # fmt: skip
    bomb = [BagFrame(0, 0.0, 0, (png.read_bytes(), "png"))]
    bag = write_bag(tmp / "vouched.bag", "ros1", vouching, bomb, load_rig(), images="png")
    runs["bag whose CameraInfo states 25000x25000"] = [
        "ingest", str(bag), "-o", str(tmp / "vouched_bag.nc"), "--no-progress",
    ]  # fmt: skip
    out = []
    for label, argv in runs.items():
        code, peak, message = command_peak(argv)
        out.append(BigFramePeak(label, code, peak, message))
    return out


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="simgap-outputs-") as name:
        tmp = Path(name)
        s = make_scenario(tmp / "scenario")
        named = 0
        for label, case in OUTPUT_CASES.items():
            kind, detail = run_case(s, case)
            named += kind == "named"
            print(f"{kind:8s} {label}: {detail[:160]}")
        print(f"{named}/{len(OUTPUT_CASES)} named")
        for peak in big_frame_peaks(tmp):
            print(
                f"{peak.label}: exit {peak.exit_code}, peak {peak.peak_mib:.0f} MiB: {peak.message}"
            )


if __name__ == "__main__":
    main()
