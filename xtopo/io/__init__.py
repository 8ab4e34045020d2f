"""Reading and writing measurements."""

from .netcdf import to_netcdf
from .container import open_container, to_container
from .open import channels, open_topography
from .formats.st_netcdf import to_surfacetopography_netcdf
from .registry import ChannelInfo, Format
from .registry import formats as list_formats

__all__ = ["open_topography", "channels", "to_netcdf", "to_surfacetopography_netcdf", "list_formats", "Format",
           "ChannelInfo", "open_container", "to_container"]
