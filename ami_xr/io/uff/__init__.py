"""Universal File Format (UFF) import and export through the ``pyuff`` package.

Modules: :mod:`.codes` (UFF code tables, point labels), :mod:`.read` (:func:`read_uff`),
:mod:`.sets` (datasets through pyuff, one at a time), :mod:`.completeness` (checks before pyuff
reads), :mod:`.records` (dataset-58 labels, abscissae, references), :mod:`.frf` and
:mod:`.time` (dataset 58 -> FRF and time Datasets), :mod:`.units` (quantities, units, dataset
164), :mod:`.nodes` (datasets 15/2411), :mod:`.modes` (dataset 55), :mod:`.write`
(:func:`write_uff`). ``pyuff`` is imported only
when a file is read or written.

What is read
------------
* Dataset 58 (ASCII or binary) with function type 4 (FRF) becomes an FRF Dataset, function type 1
  (time response) a time Dataset; coherence records (function type 6) of an FRF file become the
  ``coherence`` variable.
* Dataset 55 becomes a modal Dataset with ``eigenvalue``, ``natural_frequency``,
  ``damping_ratio`` and ``mode_vector``: complex modes (analysis type 3) from their eigenvalue;
  normal modes (analysis type 2, as FE tools write them) from their frequency f and viscous
  damping ratio zeta, ``eigenvalue = -zeta*wn + i*wn*sqrt(1 - zeta^2)`` with ``wn = 2 pi f``,
  plus ``modal_mass`` (as written; 0 means not given) and, when stated,
  ``hysteretic_damping_ratio``. Every DOF the datasets list is a point, zero or not (a node on
  a nodal line, rotations stored as 0); only in files :func:`write_uff` wrote (ID line 1
  ``ami_xr mode shapes``) the zero components are the writer's padding and are left out. When
  the file also holds FRFs (an exported identification result), the modes are added to the FRF
  Dataset, so ``ami-xr convert result.uff result.nc`` keeps them; mode shapes without a value
  at every FRF point are left out with a warning (attribute ``uff_modes_skipped``; read them
  with ``kind="modes"``).
* Datasets 15 and 2411 (node coordinates), when present, give the ``point_x``, ``point_y`` and
  ``point_z`` coordinates of every point on a known node, in metres: a dataset 164 converts them
  by its length factor (attribute ``uff_units_scaled`` on the coordinates and the Dataset).
* Lines padded with blanks (SDynPy pads every line to 80 columns) are read as if unpadded; text
  of dataset-58 headers that is not UTF-8 (``m/s²`` in Latin-1) is decoded as Latin-1; a
  dataset pyuff cannot read is a :class:`~ami_xr.errors.DataFileError` naming its place in the
  file, its type and its first line.

Point labels
------------
A UFF degree of freedom is a node number and a direction code (1, 2, 3 = +X, +Y, +Z; 4, 5, 6 =
rotations RX, RY, RZ; negative codes point the other way; 0 = scalar). It becomes the label
``f"{node}{sign}{axis}"``, e.g. ``"1+Z"`` or ``"12-X"``; a scalar DOF (direction 0) becomes the
integer node number. Labels that are neither (``"tip"``) are written with node numbers 1, 2, ...
and the label in ID line 2 (``"ami_xr point=tip"``), which the reader restores.

Completeness and validity
-------------------------
Every dataset must close with its ``    -1`` line and every dataset-58 record must hold the
``num_pts`` values its header declares; a file cut short (ASCII or binary) is a
:class:`~ami_xr.errors.DataFileError` that says where the incomplete dataset starts and how many
datasets before it are complete (pyuff alone silently drops the incomplete one). The writer
checks the Dataset first (finite ``frf``/``coherence``/``response``/``force``, a complex
``frf``, a strictly increasing abscissa of at least 2 values, unique point labels) and writes
nothing when any check fails.

Single-reference grouping and the drive point
---------------------------------------------
ami_xr's FRF Dataset holds one column of the FRF matrix: responses at many points to a force at one
drive point. A UFF file with one reference DOF and several response DOFs maps directly (points =
response DOFs, ``drive_point`` = the reference DOF). A roving-hammer file has the transpose: one
response DOF, several reference DOFs. By Maxwell-Betti reciprocity (H_rj = H_jr for a linear
system) its FRFs are the same column, so points = reference DOFs and ``drive_point`` = the fixed
response DOF; the Dataset attribute ``uff_layout`` says which case applied. Files where both
vary (multiple references) are refused with a clear error until multi-reference data is supported.

Abscissae
---------
Evenly spaced records store their increment with about 6 significant digits. When ``1 / inc``
is that close to an integer (a sampling rate in Hz or a record length in s), the exact reciprocal
is used, so ``dt = 1/1024 s`` or ``df = 1/60 Hz`` survive a round trip.

Units
-----
The response quantity comes from the ordinate's specific data type (8 displacement, 11 velocity,
12 acceleration) and the force from the denominator (13 excitation force, 9 reaction force). A
type 0 (unknown) or 1 (general) is read when the ordinate's unit label names a response unit
(``"m/s^2"``, ``"g"``, ...; attribute ``uff_quantity_from_label``) and refused otherwise; in a
time file, such a record with a force unit label is the force. For the response and the force
separately:

1. a unit label ami_xr knows (``"m/s^2"``, ``"g"``, ``"N"``, ..., case-insensitive, ``"m/s²"``
   too) is used as it is: a file in g gives an FRF in ``g/N``, values unchanged. The ordinate
   label may name the whole FRF unit (``"m/s^2/N"``, ``"(1/N)*(m/s²)"``); its force must then
   agree with the denominator label, if that names one;
2. otherwise, when the file has a units dataset 164, its length and force factors give the
   units: the values are converted to SI (SI = file value / factor, as the UFF specification
   defines the factors) and the attribute ``uff_units_scaled`` says how;
3. otherwise SI units are assumed (m, m/s, m/s^2, N): a warning says so on the terminal and the
   attribute ``uff_units_assumed`` records it.

Coherence records (function type 6) are written dimensionless: ordinate label ``"1"``, no
denominator.
"""

from ami_xr.io.uff.codes import parse_point_label, point_label
from ami_xr.io.uff.read import read_uff
from ami_xr.io.uff.write import write_uff

__all__ = ["read_uff", "write_uff", "point_label", "parse_point_label"]
