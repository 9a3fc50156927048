"""The case: schema, typed case model (mechanics + EM tables), case-file io, resource guards, reference table."""
