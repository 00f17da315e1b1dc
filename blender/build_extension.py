"""Build the installable Blender extension: blender/meshmatch with the `meshmatch` wheel.

    python blender/build_extension.py [--out DIR]

Builds the package's abi3 wheel (maturin, release), then writes DIR/meshmatch-<version>.zip
(default target/blender/) holding the add-on, its manifest with the wheel listed under `wheels`,
and the wheel in wheels/. Install it in Blender with Edit > Preferences > Get Extensions >
Install from Disk (Blender 4.2 or later, Linux x86-64).
"""

import argparse
import os
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ADDON = ROOT / "blender" / "meshmatch"


def build_wheel(out):
    out.mkdir(parents=True, exist_ok=True)
    for old in out.glob("meshmatch-*.whl"):
        old.unlink()
    cmd = [sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-w", str(out)]
    try:
        import maturin  # noqa: F401  (the backend is here: build with it, offline)

        cmd.append("--no-build-isolation")
    except ImportError:
        pass
    # maturin's build backend runs the `maturin` program beside this interpreter.
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    subprocess.run(cmd, check=True, env=env)
    wheels = sorted(out.glob("meshmatch-*.whl"))
    if len(wheels) != 1:
        sys.exit(f"expected one meshmatch wheel in {out}, found {len(wheels)}")
    return wheels[0]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "target" / "blender")
    ap.add_argument("--wheel", type=Path, help="use this wheel instead of building one")
    a = ap.parse_args()
    wheel = a.wheel or build_wheel(a.out / "wheels")
    manifest = (ADDON / "blender_manifest.toml").read_text()
    version = tomllib.loads(manifest)["version"]
    manifest = manifest.replace(
        "\n[permissions]", f'\nwheels = ["./wheels/{wheel.name}"]\n\n[permissions]', 1
    )
    tomllib.loads(manifest)  # still valid TOML
    a.out.mkdir(parents=True, exist_ok=True)
    zpath = a.out / f"meshmatch-{version}.zip"
    with zipfile.ZipFile(zpath, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted(ADDON.rglob("*")):
            rel = f.relative_to(ADDON)
            if f.is_dir() or "__pycache__" in rel.parts or rel.name == "blender_manifest.toml":
                continue
            z.write(f, rel.as_posix())
        z.writestr("blender_manifest.toml", manifest)
        z.write(wheel, f"wheels/{wheel.name}")
    print(zpath)


if __name__ == "__main__":
    main()
