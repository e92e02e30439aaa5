"""Albedo: per-view estimators (role ``albedo_estimator``) and the base-colour texture stage."""
