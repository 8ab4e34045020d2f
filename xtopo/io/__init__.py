"""Reading and writing measurements."""

from .netcdf import to_netcdf
from .open import open_topography
from .registry import ChannelInfo, Format
from .registry import formats as list_formats

__all__ = ["open_topography", "to_netcdf", "list_formats", "Format", "ChannelInfo"]
