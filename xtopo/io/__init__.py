"""Reading and writing measurements."""

from .netcdf import to_netcdf
from .open import channels, open_topography
from .registry import ChannelInfo, Format, formats

__all__ = ["open_topography", "channels", "to_netcdf", "formats", "Format", "ChannelInfo"]
