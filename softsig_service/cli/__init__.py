"""The ``softsig`` command line (typer).

MuJoCo's rendering backend is chosen (headless EGL by default) before any command module imports MuJoCo.
"""

from softsig_service.gl_backend import prepare_mujoco

prepare_mujoco()

from softsig_service.cli.main import app, main  # noqa: E402

__all__ = ["app", "main"]
