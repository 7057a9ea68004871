"""Chapter: dynamic models. Ask kinds dynamic_model (model), equilibria, linear_parametrization."""
