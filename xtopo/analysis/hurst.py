def hurst(obj, **kw):
    raise NotImplementedError
