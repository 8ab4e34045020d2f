"""Reading and writing measurements."""

from .netcdf import to_netcdf
from .open import channels, open_topography
from .formats.st_netcdf import to_surfacetopography_netcdf
from .registry import ChannelInfo, Format, formats

__all__ = ["open_topography", "channels", "to_netcdf", "to_surfacetopography_netcdf", "formats", "Format", "ChannelInfo"]
