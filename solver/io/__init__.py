"""File formats: a surface as OBJ, a network as JSON, a result as NPZ
(formats.py)."""

from .formats import (
    load_result,
    network_from_dict,
    network_to_dict,
    options_from_dict,
    read_network,
    read_obj,
    save_result,
    write_network,
    write_obj,
)

__all__ = ["load_result", "network_from_dict", "network_to_dict", "options_from_dict", "read_network", "read_obj",
           "save_result", "write_network", "write_obj"]
