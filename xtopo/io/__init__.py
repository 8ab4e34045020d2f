"""Reading and writing measurements."""

from .netcdf import to_netcdf
from .open import open_topography
from .registry import ChannelInfo, Format, formats

__all__ = ["open_topography", "to_netcdf", "formats", "Format", "ChannelInfo"]
