"""The machine file (TOML): ties a PLC program's inputs and outputs to physical consumers,
switches and input schedules. Every key is documented in ``docs/reference/machine-file.md``
and declared once in :mod:`.schema`.

* :func:`load_machine` reads and validates one (:mod:`.load`); problems are
  :class:`MachineError` naming the file, the table and the key, harmless oddities are
  collected in ``Machine.warnings``
* :func:`check_against_program` checks its signals against the program (:mod:`.bind`)
* :func:`save_machine` writes one (:mod:`.save`)
"""
from .bind import check_against_program, program_addresses
from .load import (
    as_machine,
    error_place,
    load_machine,
    locate_error,
    machine_from_data,
    machine_roots,
    read_machine_data,
    unknown_name,
)
from .model import (
                    CYLINDER_KINDS,
                    HOURS_PER_YEAR,
                    KINDS,
                    PASSIVE_KINDS,
                    Calendar,
                    Consumer,
                    InputSchedule,
                    Line,
                    Machine,
                    MachineError,
                    Meter,
)
from .save import dump_machine_toml, save_machine

__all__ = ["CYLINDER_KINDS", "HOURS_PER_YEAR", "KINDS", "PASSIVE_KINDS", "Calendar", "Consumer",
           "InputSchedule", "Line", "Machine", "MachineError", "Meter", "as_machine",
           "check_against_program", "dump_machine_toml", "error_place", "load_machine",
           "locate_error", "machine_from_data", "machine_roots", "program_addresses",
           "read_machine_data", "save_machine", "unknown_name"]
