import jax

import jaxfric  # noqa: F401  (turns on x64)


# As diffrax's test suite: strict dtype promotion catches silent float32/int mixing.
jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")
