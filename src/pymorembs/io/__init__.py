"""Reading FE models and writing files safely.

A public subpackage (``docs/api.md``, "The public surface"): :func:`read_body` reads a body in
any of :data:`FORMATS` (:func:`pymorembs.read` is the same function; :func:`model_files`
lists every file a read opens), the native HDF5
file (:func:`write_body_h5`, :func:`read_body_h5`) and plain Matrix Market files
(:func:`write_matrix_files`, :func:`read_matrix_files`); files are written atomically
(:func:`atomic_path`, :func:`write_text`), output folders checked first
(:func:`check_output_folder`).
"""

from pymorembs.io.atomic import atomic_path, check_output_folder, write_text
from pymorembs.io.formats import FORMATS, detect_format, model_files, read_body
from pymorembs.io.matrix_market import read_matrix_files, write_matrix_files
from pymorembs.io.native import read_body_h5, write_body_h5

__all__ = [
    "FORMATS",
    "atomic_path",
    "check_output_folder",
    "detect_format",
    "model_files",
    "read_body",
    "read_body_h5",
    "read_matrix_files",
    "write_body_h5",
    "write_matrix_files",
    "write_text",
]
