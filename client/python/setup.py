"""Builds the invr package's generated modules into the wheel: the gRPC stubs from ../../proto
(grpcio-tools, a build requirement in pyproject.toml) and invr/_constants.py from the C++ headers.
Everything else is in pyproject.toml."""
import subprocess
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
PROTOS = ["invr/v1/scene.proto", "invr/v1/job.proto", "invr/v1/stats.proto", "invr/v1/service.proto"]


class BuildWithGenerated(build_py):
    def run(self):
        super().run()
        out = Path(self.build_lib)
        proto_dir = ROOT / "proto"
        if not (proto_dir / PROTOS[0]).is_file():
            raise SystemExit(f"invr: {proto_dir} is missing: build the package from invr's source tree (pip install ./client/python)")
        (out / "invr" / "v1").mkdir(parents=True, exist_ok=True)
        from grpc_tools import protoc
        import grpc_tools
        include = str(Path(grpc_tools.__file__).parent / "_proto")
        args = ["protoc", f"-I{proto_dir}", f"-I{include}", f"--python_out={out}", f"--grpc_python_out={out}"] + PROTOS
        if protoc.main(args) != 0:
            raise SystemExit("invr: protoc failed on " + " ".join(PROTOS))
        (out / "invr" / "v1" / "__init__.py").touch()
        subprocess.check_call([sys.executable, str(HERE / "tools" / "gen_constants.py"), str(ROOT), str(out / "invr" / "_constants.py")])
        version = self.distribution.get_version()
        (out / "invr" / "_version.py").write_text(f'__version__ = "{version}"\n')


setup(cmdclass={"build_py": BuildWithGenerated})
