"""Operators and menu entries: Add / Apply / Remove / Update Smooth FFD, Bake / Clear Bake."""
import bpy

from . import api, core, state


def _lattice_candidate(context, obj):
    for other in context.selected_objects:
        if other is not obj and other.type == 'LATTICE':
            return other
    return None


class OBJECT_OT_smooth_ffd_add(bpy.types.Operator):
    """Add a Smooth FFD modifier (smooth free-form deformation by a lattice)"""
    bl_idname = "object.smooth_ffd_add"
    bl_label = "Smooth FFD"
    bl_options = {'REGISTER', 'UNDO'}

    # viewport_level, render_level: _level_properties (1 to the core's MAX_LEVEL)

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.type == 'MESH'

    def execute(self, context):
        obj = context.active_object
        try:
            # A selected lattice becomes the modifier's lattice, like Ctrl+P > Lattice Deform.
            mod = api.add_smooth_ffd(obj, _lattice_candidate(context, obj),
                                     self.viewport_level, self.render_level)
        except (TypeError, ValueError, RuntimeError, ImportError) as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        self.report({'INFO'}, f"{mod.name}: {api.status(mod)}")
        if state.lock_message[0]:
            self.report({'WARNING'}, state.lock_message[0])
        return {'FINISHED'}


class _ModifierOperator:
    modifier: bpy.props.StringProperty(name="Modifier", default="")

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.type == 'MESH' and bool(api.smooth_ffd_modifiers(obj))

    def _modifier(self, context):
        obj = context.active_object
        mods = api.smooth_ffd_modifiers(obj)
        if self.modifier:
            mods = [m for m in mods if m.name == self.modifier]
        return obj, (mods[0] if mods else None)

    def _clear(self, context, clear):
        """clear(obj, mod) on the chosen modifier (a bake, held counts), errors reported."""
        obj, mod = self._modifier(context)
        if mod is None:
            return {'CANCELLED'}
        try:
            clear(obj, mod)
        except RuntimeError as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        return {'FINISHED'}


class OBJECT_OT_smooth_ffd_apply(_ModifierOperator, bpy.types.Operator):
    """Apply the Smooth FFD modifier at its render level (exact normals)"""
    bl_idname = "object.smooth_ffd_apply"
    bl_label = "Apply Smooth FFD"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        obj, mod = self._modifier(context)
        if mod is None:
            self.report({'ERROR'}, "no Smooth FFD modifier")
            return {'CANCELLED'}
        wm = context.window_manager
        wm.progress_begin(0, 1)   # render-level plans of big meshes take seconds
        try:
            api.apply_smooth_ffd(obj, mod)
        except RuntimeError as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        finally:
            wm.progress_end()
        return {'FINISHED'}


class OBJECT_OT_smooth_ffd_remove(_ModifierOperator, bpy.types.Operator):
    """Remove the Smooth FFD modifier and its hidden result mesh"""
    bl_idname = "object.smooth_ffd_remove"
    bl_label = "Remove Smooth FFD"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        obj, mod = self._modifier(context)
        if mod is None:
            return {'CANCELLED'}
        try:
            api.remove_smooth_ffd(obj, mod)
        except RuntimeError as e:   # linked data, or a modifier from an override's library
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        return {'FINISHED'}


class OBJECT_OT_smooth_ffd_bake(_ModifierOperator, bpy.types.Operator):
    """Bake a frame range of the Smooth FFD result into the file, at the render level, so that
    Blender without the add-on (render farms) renders those frames"""
    bl_idname = "object.smooth_ffd_bake"
    bl_label = "Bake Smooth FFD"
    bl_options = {'REGISTER', 'UNDO'}

    frame_start: bpy.props.IntProperty(name="Start", default=1)
    frame_end: bpy.props.IntProperty(name="End", default=250)

    def invoke(self, context, event):
        self.frame_start, self.frame_end = context.scene.frame_start, context.scene.frame_end
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context):
        obj, mod = self._modifier(context)
        if mod is None:
            self.report({'ERROR'}, "no Smooth FFD modifier")
            return {'CANCELLED'}
        wm = context.window_manager
        wm.progress_begin(0, 1)
        try:
            meshes = api.bake_smooth_ffd(obj, mod, self.frame_start, self.frame_end)
        except (RuntimeError, ValueError) as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        finally:
            wm.progress_end()
        self.report({'INFO'}, f"{mod.name}: baked frames {self.frame_start}-{self.frame_end} "
                              f"({meshes} distinct meshes)")
        return {'FINISHED'}


class OBJECT_OT_smooth_ffd_bake_clear(_ModifierOperator, bpy.types.Operator):
    """Remove the Smooth FFD bake: the modifier computes live again on those frames"""
    bl_idname = "object.smooth_ffd_bake_clear"
    bl_label = "Clear Smooth FFD Bake"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        return self._clear(context, api.clear_bake)


class OBJECT_OT_smooth_ffd_hold(_ModifierOperator, bpy.types.Operator):
    """Hold the adaptive tessellation (Tolerance, Screen) over a frame range: those frames
    share one topology, the finest any of them needs (caches, motion blur)"""
    bl_idname = "object.smooth_ffd_hold"
    bl_label = "Hold Smooth FFD Tessellation"
    bl_options = {'REGISTER', 'UNDO'}

    frame_start: bpy.props.IntProperty(name="Start", default=1)
    frame_end: bpy.props.IntProperty(name="End", default=250)

    def invoke(self, context, event):
        self.frame_start, self.frame_end = context.scene.frame_start, context.scene.frame_end
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context):
        obj, mod = self._modifier(context)
        if mod is None:
            self.report({'ERROR'}, "no Smooth FFD modifier")
            return {'CANCELLED'}
        try:
            kinds = api.hold_tessellation(obj, mod, self.frame_start, self.frame_end)
        except (RuntimeError, ValueError) as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        self.report({'INFO'}, f"{mod.name}: {' and '.join(kinds)} tessellation held over "
                              f"frames {self.frame_start}-{self.frame_end}")
        return {'FINISHED'}


class OBJECT_OT_smooth_ffd_hold_clear(_ModifierOperator, bpy.types.Operator):
    """Let every frame take its own adaptive tessellation again"""
    bl_idname = "object.smooth_ffd_hold_clear"
    bl_label = "Clear Smooth FFD Held Tessellation"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        return self._clear(context, api.clear_hold)


class OBJECT_OT_smooth_ffd_update(bpy.types.Operator):
    """Recompute every Smooth FFD result now"""
    bl_idname = "object.smooth_ffd_update"
    bl_label = "Update Smooth FFD"
    bl_options = {'REGISTER'}

    def execute(self, context):
        api.update(force=True)
        return {'FINISHED'}


class OBJECT_MT_smooth_ffd(bpy.types.Menu):
    bl_idname = "OBJECT_MT_smooth_ffd"
    bl_label = "Smooth FFD"

    def draw(self, context):
        layout = self.layout
        layout.operator(OBJECT_OT_smooth_ffd_add.bl_idname, text="Add Smooth FFD")
        layout.operator(OBJECT_OT_smooth_ffd_apply.bl_idname, text="Apply")
        layout.operator(OBJECT_OT_smooth_ffd_remove.bl_idname, text="Remove")
        layout.operator(OBJECT_OT_smooth_ffd_bake.bl_idname, text="Bake...")
        layout.operator(OBJECT_OT_smooth_ffd_bake_clear.bl_idname, text="Clear Bake")
        layout.operator(OBJECT_OT_smooth_ffd_hold.bl_idname, text="Hold Tessellation...")
        layout.operator(OBJECT_OT_smooth_ffd_hold_clear.bl_idname, text="Clear Held Tessellation")
        layout.operator(OBJECT_OT_smooth_ffd_update.bl_idname, text="Update All")


def _object_menu(self, context):
    self.layout.menu(OBJECT_MT_smooth_ffd.bl_idname)


def _add_modifier_menu(self, context):
    self.layout.operator(OBJECT_OT_smooth_ffd_add.bl_idname, text="Smooth FFD", icon='MOD_LATTICE')


CLASSES = (
    OBJECT_OT_smooth_ffd_add,
    OBJECT_OT_smooth_ffd_apply,
    OBJECT_OT_smooth_ffd_remove,
    OBJECT_OT_smooth_ffd_bake,
    OBJECT_OT_smooth_ffd_bake_clear,
    OBJECT_OT_smooth_ffd_hold,
    OBJECT_OT_smooth_ffd_hold_clear,
    OBJECT_OT_smooth_ffd_update,
    OBJECT_MT_smooth_ffd,
)


def _modifier_menus():
    """Where users add modifiers: the Deform submenu from 4.0, the add-modifier operator's
    dropdown has no Python hook before that, so 3.x gets the Object menu entry only."""
    names = ("OBJECT_MT_modifier_add_deform",)
    return [getattr(bpy.types, n) for n in names if hasattr(bpy.types, n)]


def _level_properties():
    """The Add operator's levels, 1 to the core's MAX_LEVEL (without a maximum when the core
    does not import: the operator then reports that error)."""
    try:
        top = {"max": core.smoothffd().MAX_LEVEL}
    except ImportError:
        top = {}
    props = OBJECT_OT_smooth_ffd_add.__annotations__
    props["viewport_level"] = bpy.props.IntProperty(name="Viewport Level", default=3, min=1, **top)
    props["render_level"] = bpy.props.IntProperty(name="Render Level", default=10, min=1, **top)


def register():
    _level_properties()
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.VIEW3D_MT_object.append(_object_menu)
    for menu in _modifier_menus():
        menu.append(_add_modifier_menu)


def unregister():
    for menu in _modifier_menus():
        menu.remove(_add_modifier_menu)
    bpy.types.VIEW3D_MT_object.remove(_object_menu)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
